// What an interrupted process leaves (penumbra/interrupt.hpp), and the registry of temporary
// files it removes (temporary_files.hpp).
//
// The handler may run on any thread, between any two instructions. Every change to the
// registry, with the file-system change it records, happens under a Change; a signal that comes
// then is only noted in `g_state`, and acted on when the outermost Change ends. A handler that
// acts marks the process as dying first, and a Change begun after that waits for the end. So the
// registry is read only while nobody changes it, and the handler does nothing but read memory,
// unlink, write, sigaction, sigprocmask and raise (all async-signal-safe).
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include "penumbra/interrupt.hpp"
#include "temporary_files.hpp"

namespace penumbra {
namespace {

// Bits 0-15: Changes under way; 16-23: the signal noted meanwhile; 31: dying.
std::atomic<uint32_t> g_state{0};
static_assert(std::atomic<uint32_t>::is_always_lock_free);
constexpr uint32_t kDepth = 0xffff, kDying = 1u << 31;
constexpr int kSignalShift = 16;
constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP};

// For the functions a signal handler runs: AddressSanitizer precedes every call of a function
// that never returns with __asan_handle_no_return, which allocates (pthread_getattr_np); a
// signal that arrived inside malloc then waited for ever on the allocator's lock (seen in
// Interrupt.TuneLeavesNoDatabaseHalfWritten under the asan preset). Not instrumented, they
// call nothing that allocates.
#define SIGNAL_HANDLER_CODE __attribute__((no_sanitize("address")))

struct Registry {
  std::vector<std::pair<std::string, std::string>> live;  // temporary, destination
  std::unordered_set<std::string> kept;  // a file rewritten (a checkpoint) counts once
  // What the handler reads besides: plain values, kept up to date by the changes.
  unsigned kept_count = 0;
  bool note_due = false;
  std::string last_kept, program = "penumbra", activity, note, note_once_kept;
  bool tty = false;  // stderr is a terminal: the line starts on a line of its own
};
// Never destroyed: a handler on another thread may read it while the main thread exits.
Registry& g_registry = *new Registry;

// One line built in place, cut at its capacity.
class Line {
 public:
  Line& operator<<(const char* s) {
    while (*s && size_ < sizeof text_ - 1) text_[size_++] = *s++;
    return *this;
  }
  Line& operator<<(const std::string& s) { return *this << s.c_str(); }
  Line& operator<<(unsigned n) {
    char digits[16];
    int k = 0;
    do digits[k++] = char('0' + n % 10);
    while ((n /= 10) > 0 && k < 15);
    while (k > 0 && size_ < sizeof text_ - 1) text_[size_++] = digits[--k];
    return *this;
  }
  void write_to(int fd) {
    text_[size_++] = '\n';
    for (size_t done = 0; done < size_;) {
      const ssize_t n = ::write(fd, text_ + done, size_ - done);
      if (n <= 0) return;
      done += size_t(n);
    }
  }

 private:
  char text_[4096];
  size_t size_ = 0;
};

const char* signal_name(int sig) {
  return sig == SIGINT    ? "SIGINT"
         : sig == SIGTERM ? "SIGTERM"
         : sig == SIGHUP  ? "SIGHUP"
                          : "a signal";
}

SIGNAL_HANDLER_CODE void say_what_is_left(int sig, unsigned removed) {
  const Registry& r = g_registry;
  Line line;
  line << (r.tty ? "\n" : "") << r.program << ": interrupted by " << signal_name(sig);
  if (!r.activity.empty()) line << " during " << r.activity;
  if (removed == 0) line << "; no file was being written";
  if (removed == 1) line << "; removed the unfinished " << r.live.front().second;
  if (removed > 1)
    line << "; removed " << removed << " unfinished files (" << r.live.front().second << ", ...)";
  if (r.kept_count == 0) line << "; no file was finished";
  if (r.kept_count == 1) line << "; kept " << r.last_kept;
  if (r.kept_count > 1)
    line << "; kept the " << r.kept_count << " files it finished, the last " << r.last_kept;
  if (r.note_due) line << "; " << r.note;
  line.write_to(STDERR_FILENO);
}

// With kDying set: nobody changes the registry any more.
[[noreturn]] SIGNAL_HANDLER_CODE void end_process(int sig) {
  sigset_t handled;
  sigemptyset(&handled);
  for (int s : kSignals) sigaddset(&handled, s);
  sigprocmask(SIG_BLOCK, &handled, nullptr);  // no second handler on this thread
  for (const auto& file : g_registry.live) ::unlink(file.first.c_str());
  say_what_is_left(sig, unsigned(g_registry.live.size()));
  // The signal's default action: the parent sees what ended the process.
  struct sigaction default_action {};
  default_action.sa_handler = SIG_DFL;
  sigemptyset(&default_action.sa_mask);
  sigaction(sig, &default_action, nullptr);
  sigset_t only;
  sigemptyset(&only);
  sigaddset(&only, sig);
  sigprocmask(SIG_UNBLOCK, &only, nullptr);
  raise(sig);
  _exit(128 + sig);
}

[[noreturn]] SIGNAL_HANDLER_CODE void wait_for_the_end() {
  for (;;) ::pause();
}

SIGNAL_HANDLER_CODE void on_signal(int sig) {
  uint32_t s = g_state.load();
  for (;;) {
    if (s & kDying) wait_for_the_end();
    const bool busy = (s & kDepth) != 0;
    const bool noted = (s >> kSignalShift & 0xff) != 0;
    const uint32_t next = !busy   ? kDying | uint32_t(sig) << kSignalShift
                          : noted ? s
                                  : s | uint32_t(sig) << kSignalShift;
    if (g_state.compare_exchange_weak(s, next)) {
      if (!busy) end_process(sig);
      return;
    }
  }
}

}  // namespace

namespace temporary_files {

Change::Change() {
  uint32_t s = g_state.load();
  for (;;) {
    if (s & kDying) wait_for_the_end();
    if (g_state.compare_exchange_weak(s, s + 1)) return;
  }
}

Change::~Change() {
  uint32_t s = g_state.load();
  for (;;) {
    const uint32_t sig = s >> kSignalShift & 0xff;
    const uint32_t next = (s & kDepth) == 1 && sig != 0 ? kDying | sig << kSignalShift : s - 1;
    if (g_state.compare_exchange_weak(s, next)) {
      if (next & kDying) end_process(int(sig));
      return;
    }
  }
}

void add(const std::string& temporary, const std::string& destination) {
  g_registry.live.emplace_back(temporary, destination);
}

void remove(const std::string& temporary) noexcept {
  auto& live = g_registry.live;
  for (auto it = live.begin(); it != live.end(); ++it) {
    if (it->first == temporary) {
      live.erase(it);
      return;
    }
  }
}

void kept(const std::string& destination) {
  Registry& r = g_registry;
  r.kept_count += r.kept.insert(destination).second;
  r.last_kept = destination;
  r.note_due = r.note_due || (!r.note.empty() && destination == r.note_once_kept);
}

void test_signal(const char* point, const std::string& destination) {
  const char* spec = std::getenv("PENUMBRA_TEST_SIGNAL");
  if (spec == nullptr) return;
  const std::string s = spec, name = destination.substr(destination.find_last_of('/') + 1);
  const size_t space = s.find(' ');
  if (space == std::string::npos || s.substr(space + 1) != std::string(point) + ":" + name) return;
  const std::string word = s.substr(0, space);
  for (int sig : kSignals)
    if ("SIG" + word == signal_name(sig)) raise(sig);
}

}  // namespace temporary_files

void install_interrupt_handlers(const std::string& program) {
  {
    temporary_files::Change change;
    g_registry.program = program;
    g_registry.tty = ::isatty(STDERR_FILENO) == 1;
  }
  struct sigaction action {};
  action.sa_handler = on_signal;
  action.sa_flags = SA_RESTART;  // a noted signal does not fail the system call it interrupts
  sigemptyset(&action.sa_mask);
  for (int s : kSignals) sigaddset(&action.sa_mask, s);
  for (int s : kSignals) {
    // A signal ignored by whoever started the process (nohup, `&` in a script) stays ignored.
    struct sigaction old {};
    if (sigaction(s, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    sigaction(s, &action, nullptr);
  }
}

void set_interrupted_activity(const std::string& what) {
  temporary_files::Change change;
  g_registry.activity = what;
}

void set_interrupted_note(const std::string& note, const std::string& once_kept) {
  temporary_files::Change change;
  Registry& r = g_registry;
  r.note = note;
  r.note_once_kept = once_kept;
  r.note_due = !note.empty() && (once_kept.empty() || r.kept.count(once_kept) != 0);
}

}  // namespace penumbra
