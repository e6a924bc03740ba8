// Text helpers of the file readers (text.hpp).
#include "text.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <vector>

#include "penumbra/error.hpp"

namespace penumbra {

std::string printable(const std::string& text, size_t max) {
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (size_t i = 0; i < text.size(); ++i) {
    if (i == max) return out + "...";
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += char(c);
    } else {
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  return out;
}

namespace {

// Follows the parser through the document (nlohmann's parser callback) and throws on the
// second occurrence of a key in one object, or on nesting beyond kMaxDepth. Each open object or
// array is a frame: the keys seen so far, or the index of the next element.
class DuplicateKeyCheck {
 public:
  // Far beyond any scene, and refused at once: each level's path is kept, so a document nested
  // a hundred thousand levels deep would take time and memory quadratic in its depth.
  static constexpr size_t kMaxDepth = 64;

  bool operator()(int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    switch (event) {
      case Event::key:
        if (!frames_.back().keys.insert(parsed.get<std::string>()).second)
          throw Error("duplicate key '" + path(parsed.get<std::string>()) +
                      "' (each key may appear once in an object)");
        frames_.back().key = parsed.get<std::string>();
        break;
      case Event::object_start:
      case Event::array_start:
        if (frames_.size() == kMaxDepth)
          throw Error("'" + printable(name_of_next(), 40) + "' is nested deeper than " +
                      std::to_string(kMaxDepth) + " levels of objects and arrays");
        frames_.push_back({event == Event::object_start, name_of_next(), {}, "", 0});
        break;
      case Event::object_end:
      case Event::array_end:
        frames_.pop_back();
        element_done();
        break;
      case Event::value:
        element_done();
        break;
    }
    return true;
  }

 private:
  struct Frame {
    bool object;
    std::string name;  // its path: "", "cameras", "cameras[0]"
    std::set<std::string> keys;
    std::string key;  // the current key of an object
    size_t index;     // the next element of an array
  };
  // The path of the value about to start.
  std::string name_of_next() const {
    if (frames_.empty()) return "";
    const Frame& f = frames_.back();
    return f.object ? path(f.key) : f.name + "[" + std::to_string(f.index) + "]";
  }
  std::string path(const std::string& key) const {
    const std::string& outer = frames_.back().name;
    return outer.empty() ? key : outer + "." + key;
  }
  void element_done() {
    if (!frames_.empty() && !frames_.back().object) ++frames_.back().index;
  }
  std::vector<Frame> frames_;
};

}  // namespace

nlohmann::json parse_json(const std::string& text) {
  return nlohmann::json::parse(text, DuplicateKeyCheck());
}

std::string quoted_path(const std::string& path) { return "'" + path + "'"; }

std::string one_line(const std::string& text) {
  std::string out;
  bool space = false;
  for (char c : text) {
    if (c == '\n' || c == '\r' || c == '\t' || c == ' ') {
      space = !out.empty();
      continue;
    }
    if (space) out += ' ';
    space = false;
    out += c;
  }
  return out;
}

std::string read_whole_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error("cannot read " + what + " " + quoted_path(path) + ": it is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw Error("cannot open " + what + " " + quoted_path(path) + ": " + std::strerror(errno));
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw Error("cannot read " + what + " " + quoted_path(path));
  return s.str();
}

void check_image(const Image& image, const std::string& what, const std::string& path) {
  if (image.width <= 0 || image.height <= 0 || image.channels <= 0)
    throw Error("cannot write " + what + " " + quoted_path(path) + ": image is empty (" +
                std::to_string(image.width) + "x" + std::to_string(image.height) + "x" +
                std::to_string(image.channels) + ")");
  const size_t want = size_t(image.width) * size_t(image.height) * size_t(image.channels);
  if (image.data.size() != want)
    throw Error("cannot write " + what + " " + quoted_path(path) + ": image has " +
                std::to_string(image.data.size()) + " values, " + std::to_string(image.width) +
                "x" + std::to_string(image.height) + "x" + std::to_string(image.channels) +
                " needs " + std::to_string(want));
}

}  // namespace penumbra
