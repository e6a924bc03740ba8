// Progress of long library calls on stderr (common.hpp, CallProgress).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>

#include "common.hpp"

namespace penumbra::cli {

CallProgress::CallProgress(std::string name)
    : name_(std::move(name)), tty_(isatty(STDERR_FILENO) == 1) {
  if (const char* after = std::getenv("PENUMBRA_PROGRESS_AFTER")) {
    char* end = nullptr;
    const double s = std::strtod(after, &end);
    if (end != after && *end == '\0' && s >= 0 && std::isfinite(s)) after_s_ = s;
  }
  start();
}

CallProgress::~CallProgress() { finish(); }

void CallProgress::watch(Renderer& renderer) {
  renderer.set_progress([this](const RenderProgress& p) { update(p); });
}

void CallProgress::start(std::string what) {
  finish();
  what_ = std::move(what);
  start_ = std::chrono::steady_clock::now();
  decile_ = -1;
}

void CallProgress::finish() {
  if (drawn_) std::fputc('\n', stderr), std::fflush(stderr);
  drawn_ = false;
}

void CallProgress::update(const RenderProgress& p) {
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  if (seconds < after_s_) return;
  const int decile = std::clamp(int(p.fraction * 10), 0, 10);
  if (!tty_ && decile <= decile_) return;
  decile_ = decile;
  std::string line = name_ + ": " + (what_.empty() ? "" : what_ + ", ") + p.call + " " + p.pass +
                     " " + std::to_string(p.index) + "/" + std::to_string(p.count) + ", " + p.stage;
  if (p.parts > 0) line += " " + std::to_string(p.part) + "/" + std::to_string(p.parts);
  char tail[64];
  std::snprintf(tail, sizeof tail, ", %d %%, %.1f s", int(p.fraction * 100), seconds);
  line += tail;
  if (tty_) {
    std::fprintf(stderr, "\r%-78s", line.c_str());
    drawn_ = true;
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  std::fflush(stderr);
}

}  // namespace penumbra::cli
