#pragma once
// SharedArray: the array type of a mesh's faces and albedo, which copies of a scene share.
#include <atomic>
#include <cstddef>
#include <initializer_list>
#include <memory>
#include <utility>
#include <vector>

namespace penumbra {

// An array that copies share until one of them is written: copying it copies a pointer, and
// shares() tells in O(1) that two arrays are one. A Renderer keeps the meshes it rendered as such
// copies, so a call whose faces and albedo are the last call's is known as such without
// comparing them. Writes go through whole-array calls (assignment, push_back, edit, …), each of
// which first gives this array its own copy where another shares it; no call hands out a
// reference to write through, so no write reaches another copy.
template <class T>
class SharedArray {
 public:
  using value_type = T;
  using const_iterator = typename std::vector<T>::const_iterator;

  SharedArray() = default;
  SharedArray(std::vector<T> values)  // implicit: a vector is an array's values
      : values_(std::make_shared<std::vector<T>>(std::move(values))) {}
  SharedArray(std::initializer_list<T> values) : SharedArray(std::vector<T>(values)) {}

  // Reading: the values as a vector (also implicitly, for a const std::vector<T>& parameter).
  const std::vector<T>& values() const { return values_ ? *values_ : none(); }
  operator const std::vector<T>&() const { return values(); }
  size_t size() const { return values().size(); }
  bool empty() const { return values().empty(); }
  const T& operator[](size_t i) const { return values()[i]; }
  const T& front() const { return values().front(); }
  const T* data() const { return values().data(); }
  const_iterator begin() const { return values().begin(); }
  const_iterator end() const { return values().end(); }
  // Whether this array and `other` are one (copies of each other, neither written since).
  bool shares(const SharedArray& other) const { return values_ == other.values_; }

  // Writing. edit(f) calls f(std::vector<T>&) on this array's own values, to change them in place.
  template <class Edit>
  void edit(Edit&& f) {
    std::forward<Edit>(f)(own());
  }
  void push_back(const T& value) { own().push_back(value); }
  template <class... Args>
  void emplace_back(Args&&... args) {
    own().emplace_back(std::forward<Args>(args)...);
  }
  void pop_back() { own().pop_back(); }
  void assign(size_t n, const T& value) { own().assign(n, value); }
  void resize(size_t n) { own().resize(n); }
  void reserve(size_t n) { own().reserve(n); }
  void clear() { values_.reset(); }

  friend bool operator==(const SharedArray& a, const SharedArray& b) {
    return a.shares(b) || a.values() == b.values();
  }
  friend bool operator==(const SharedArray& a, const std::vector<T>& b) { return a.values() == b; }

 private:
  static const std::vector<T>& none() {
    static const std::vector<T> empty;
    return empty;
  }
  // The values, this array's alone: copied first where another array shares them.
  std::vector<T>& own() {
    if (!values_) {
      values_ = std::make_shared<std::vector<T>>();
    } else if (values_.use_count() > 1) {
      values_ = std::make_shared<std::vector<T>>(*values_);
    } else {
      // The last other holder may have let go on another thread: its reads happen before ours.
      std::atomic_thread_fence(std::memory_order_acquire);
    }
    return *values_;
  }
  std::shared_ptr<std::vector<T>> values_;
};

}  // namespace penumbra
