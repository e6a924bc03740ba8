// Progress lines of the applications (ProgressPrinter) and the IoU list of their last line.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "penumbra/optim.hpp"

namespace penumbra::optim {

ProgressPrinter::ProgressPrinter(std::string name, int total, int every)
    : name_(std::move(name)),
      total_(std::max(total, 1)),
      every_(every > 0 ? every : std::max(1, total / 10)),
      tty_(isatty(STDERR_FILENO) == 1) {}

void ProgressPrinter::update(int iteration, double loss, const std::vector<double>& ious,
                             double seconds) {
  const bool last = iteration >= total_;
  if (!tty_ && !last && iteration % every_ != 0) return;
  constexpr int kWidth = 20;
  const int filled = std::clamp(int(double(kWidth) * iteration / total_), 0, kWidth);
  std::fprintf(stderr, "%s%s [%s%s] %d/%d  loss %.4f  iou %s  %.1f s%s", tty_ ? "\r" : "",
               name_.c_str(), std::string(size_t(filled), '#').c_str(),
               std::string(size_t(kWidth - filled), '.').c_str(), iteration, total_, loss,
               iou_list(ious).c_str(), seconds, tty_ ? " " : "\n");
  if (tty_ && last) std::fputc('\n', stderr);
  std::fflush(stderr);
}

std::string iou_list(const std::vector<double>& ious) {
  std::string s = "[";
  for (size_t i = 0; i < ious.size(); ++i) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s%.3f", i ? "," : "", ious[i]);
    s += buf;
  }
  return s + "]";
}

}  // namespace penumbra::optim
