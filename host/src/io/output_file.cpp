// Every file penumbra writes goes through OutputFile (io.hpp).
//
// A regular file (or a name that does not exist yet) is written to a temporary file in the
// destination's folder — ".<name>.<pid>.<n>.tmp", created exclusively — every write and the
// close are checked, and only then is it renamed over the destination, so that a reader sees
// either the old file or the whole new one. Any failure removes the temporary file and throws
// one line naming the destination and the reason (strerror). A destination that exists and is
// not a regular file (/dev/null, /dev/full, a named pipe) is written directly, still checked.
// The temporary files are listed in the registry an interruption empties (interrupt.cpp); each
// is created, renamed or removed under a Change, so that a signal cannot fall between the file
// system and the list.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

#include "penumbra/error.hpp"
#include "penumbra/io.hpp"
#include "temporary_files.hpp"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

// The file a rename should replace: `path` itself, or the file a symbolic link names (so
// that the link survives).
std::string rename_target(const std::string& path) {
  struct stat link;
  if (::lstat(path.c_str(), &link) != 0 || !S_ISLNK(link.st_mode)) return path;
  std::error_code ec;
  const fs::path resolved = fs::canonical(path, ec);
  return ec ? path : resolved.string();
}

std::string temporary_name(const std::string& target) {
  static std::atomic<unsigned> counter{0};
  const fs::path p(target);
  return (p.parent_path() / ("." + p.filename().string() + "." + std::to_string(::getpid()) + "." +
                             std::to_string(counter++) + ".tmp"))
      .string();
}

}  // namespace

OutputFile::OutputFile(const std::string& path, const std::string& what, FileKind kind)
    : path_(path), what_(what), kind_(kind) {
  if (path.empty()) fail("the path is empty");
  struct stat st;
  const bool exists = ::stat(path.c_str(), &st) == 0;
  if (exists && !S_ISREG(st.st_mode)) {  // a device, a pipe, a folder: written in place
    fd_ = ::open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
    if (fd_ < 0) fail(std::strerror(errno));
    return;
  }
  target_ = rename_target(path);
  const mode_t mode = exists ? (st.st_mode & 07777) : 0666;  // 0666 less the umask when new
  temporary_files::Change change;
  for (int attempt = 0; fd_ < 0; ++attempt) {
    temporary_ = temporary_name(target_);
    fd_ = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd_ < 0 && (errno != EEXIST || attempt == 100)) {
      const int error = errno;
      temporary_.clear();
      fail(std::strerror(error));
    }
  }
  temporary_files::add(temporary_, path_);
  if (exists && ::fchmod(fd_, mode) != 0) fail(std::strerror(errno));
}

OutputFile::~OutputFile() { discard(); }

void OutputFile::write(const void* data, size_t size) {
  if (fd_ < 0) fail(committed_ ? "already written" : "already closed");
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd_, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail(n < 0 ? std::strerror(errno) : "write wrote nothing");
    p += n;
    size -= size_t(n);
  }
}

void OutputFile::write(const std::string& bytes) { write(bytes.data(), bytes.size()); }

void OutputFile::close() {
  if (fd_ < 0) return;
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail(std::strerror(errno));
  if (!temporary_.empty()) temporary_files::test_signal("written", path_);
}

void OutputFile::commit() {
  if (committed_) return;
  close();
  temporary_files::Change change;
  if (!temporary_.empty()) {
    temporary_files::test_signal("renaming", path_);
    if (::rename(temporary_.c_str(), target_.c_str()) != 0) fail(std::strerror(errno));
    temporary_files::remove(temporary_);
    if (kind_ == FileKind::output) temporary_files::kept(path_);
  }
  temporary_.clear();
  committed_ = true;
}

void OutputFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (temporary_.empty()) return;
  temporary_files::Change change;
  ::unlink(temporary_.c_str());
  temporary_files::remove(temporary_);
  temporary_.clear();
}

void OutputFile::fail(const std::string& reason) {
  discard();
  throw Error("cannot write " + what_ + " '" + path_ + "': " + reason);
}

void write_file(const std::string& path, const std::string& bytes, const std::string& what,
                FileKind kind) {
  OutputFile file(path, what, kind);
  file.write(bytes);
  file.commit();
}

void write_files(const std::vector<FileContent>& files) {
  std::vector<std::unique_ptr<OutputFile>> staged;
  for (const FileContent& f : files) {
    staged.push_back(std::make_unique<OutputFile>(f.path, f.what));
    staged.back()->write(f.bytes);
    staged.back()->close();
  }
  temporary_files::Change change;  // all renamed, even when a signal comes meanwhile
  for (auto& file : staged) file->commit();
}

void check_writable(const std::string& path, const std::string& what) {
  OutputFile probe(path, what);  // creates the temporary file a write would, then removes it
}

}  // namespace penumbra
