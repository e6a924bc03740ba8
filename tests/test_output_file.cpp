// OutputFile (penumbra/io.hpp), the writer of every file penumbra writes: a temporary file in
// the destination folder, checked writes and close, renamed into place, so that a failure
// leaves nothing at the destination and an earlier file there untouched (docs/faults.md,
// "Writing files").
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "cli_run.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "scenes.hpp"

namespace fs = std::filesystem;
using namespace penumbra_tests;

namespace {

std::string fresh_dir(const std::string& name) { return fresh_temp_dir("output_file_" + name); }

// A grey image of noise whose .npy is `bytes` long, give or take the header (noise, so that
// its GIF does not compress either).
penumbra::Image image_of_bytes(size_t bytes) {
  const int side = int(std::ceil(std::sqrt(double(bytes) / 4.0)));
  penumbra::Image image(side, side, 1);
  unsigned state = 12345;
  for (double& v : image.data) v = ((state = state * 1103515245u + 12345u) >> 16) % 256 / 255.0;
  return image;
}

// Runs `fn` in a forked child under a file-size limit of `limit` bytes (SIGXFSZ ignored, so
// that a write past it fails with EFBIG); returns the message of the error it threw.
std::string error_under_file_size_limit(rlim_t limit, const std::function<void()>& fn) {
  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) return "pipe failed";
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(pipe_fds[0]);
    ::signal(SIGXFSZ, SIG_IGN);
    const rlimit r{limit, limit};
    std::string message = ::setrlimit(RLIMIT_FSIZE, &r) == 0 ? error_of(fn) : "setrlimit failed";
    if (message.empty()) message = "(no error)";
    (void)!::write(pipe_fds[1], message.data(), message.size());
    ::_exit(0);
  }
  ::close(pipe_fds[1]);
  std::string message;
  char buffer[512];
  for (ssize_t n; (n = ::read(pipe_fds[0], buffer, sizeof buffer)) > 0;) message.append(buffer, n);
  ::close(pipe_fds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  return message;
}

// ---------------------------------------------------------------------------------------------
// The writer itself.

TEST(OutputFile, WritesTheWholeFileAndNoTemporaryStays) {
  const std::string dir = fresh_dir("whole");
  const std::string path = dir + "/a.npy";
  const penumbra::Image image(5, 4, 3, 0.5);
  penumbra::save_npy(image, path);
  EXPECT_EQ(read_text(path), penumbra::npy_bytes(image, path));
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"a.npy"});
  penumbra::save_npy(penumbra::Image(2, 2, 1, 1.0), path);  // replaces it
  EXPECT_EQ(penumbra::load_npy(path).width, 2);
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"a.npy"});
}

TEST(OutputFile, DevFullIsAnErrorNamingThePathAndTheReason) {
  const std::string message =
      error_of([] { penumbra::save_png(penumbra::Image(8, 8, 3, 0.5), "/dev/full"); });
  EXPECT_NE(message.find("cannot write PNG '/dev/full'"), std::string::npos) << message;
  EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
}

TEST(OutputFile, DevNullIsWrittenDirectly) {
  EXPECT_EQ(error_of([] { penumbra::save_npy(penumbra::Image(8, 8, 3, 0.5), "/dev/null"); }), "");
  struct stat st;
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));  // still the device, not a file renamed over it
}

TEST(OutputFile, NamedPipeIsWrittenDirectly) {
  const std::string dir = fresh_dir("fifo");
  const std::string fifo = dir + "/pipe.npy";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = read_text(fifo); });
  const penumbra::Image image(16, 16, 3, 0.75);
  const std::string message = error_of([&] { penumbra::save_npy(image, fifo); });
  reader.join();
  EXPECT_EQ(message, "");
  EXPECT_EQ(received, penumbra::npy_bytes(image, fifo));
}

TEST(OutputFile, FileSizeLimitLeavesTheEarlierFileUntouched) {
  const std::string dir = fresh_dir("fsize");
  const std::string path = dir + "/out.npy";
  write_text(path, "the earlier file");
  const std::string message = error_under_file_size_limit(
      64 * 1024, [&] { penumbra::save_npy(image_of_bytes(1 << 20), path); });
  EXPECT_NE(message.find("cannot write NumPy file '" + path + "'"), std::string::npos) << message;
  EXPECT_NE(message.find("File too large"), std::string::npos) << message;
  EXPECT_EQ(read_text(path), "the earlier file");
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"out.npy"});  // no temporary left
}

TEST(OutputFile, FileSizeLimitOnANewFileLeavesNothing) {
  const std::string dir = fresh_dir("fsize_new");
  const std::string message = error_under_file_size_limit(64 * 1024, [&] {
    penumbra::save_gif({image_of_bytes(1 << 22), image_of_bytes(1 << 22)}, dir + "/a.gif");
  });
  EXPECT_NE(message.find("cannot write"), std::string::npos) << message;
  EXPECT_TRUE(names_in(dir).empty());
}

TEST(OutputFile, FolderThatCannotHoldFilesIsAnError) {
  // As root, permissions do not stop a write; a path under a regular file does.
  const std::string dir = fresh_dir("notdir");
  write_text(dir + "/file", "x");
  const std::string message =
      error_of([&] { penumbra::save_png(penumbra::Image(4, 4, 1), dir + "/file/x.png"); });
  EXPECT_NE(message.find("cannot write PNG '" + dir + "/file/x.png': Not a directory"),
            std::string::npos)
      << message;
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"file"});
}

TEST(OutputFile, ReadOnlySysfsFolderIsAnErrorEvenForRoot) {
  if (!fs::is_directory("/sys/kernel")) GTEST_SKIP() << "no /sys here";
  const std::string message =
      error_of([] { penumbra::save_png(penumbra::Image(4, 4, 1), "/sys/kernel/penumbra.png"); });
  EXPECT_NE(message.find("cannot write PNG '/sys/kernel/penumbra.png': "), std::string::npos)
      << message;
}

TEST(OutputFile, FolderAtTheDestinationIsAnErrorAndStays) {
  const std::string dir = fresh_dir("isdir");
  fs::create_directories(dir + "/out.png/inside");
  const std::string message =
      error_of([&] { penumbra::save_png(penumbra::Image(4, 4, 1), dir + "/out.png"); });
  EXPECT_NE(message.find("cannot write PNG '" + dir + "/out.png': Is a directory"),
            std::string::npos)
      << message;
  EXPECT_TRUE(fs::is_directory(dir + "/out.png/inside"));
}

TEST(OutputFile, UncommittedFileLeavesNothing) {
  const std::string dir = fresh_dir("uncommitted");
  {
    penumbra::OutputFile file(dir + "/a.txt", "text file");
    file.write("half of it");
    EXPECT_EQ(names_in(dir).size(), 1u);  // the temporary file
  }
  EXPECT_TRUE(names_in(dir).empty());
  {
    penumbra::GifWriter gif(dir + "/a.gif", 4, 4);
    gif.add_frame(penumbra::Image(4, 4, 3, 0.5));
  }  // destroyed without close()
  EXPECT_TRUE(names_in(dir).empty());
}

TEST(OutputFile, SymbolicLinkKeepsPointingAtTheNewFile) {
  const std::string dir = fresh_dir("symlink");
  write_text(dir + "/real.txt", "old");
  fs::create_symlink("real.txt", dir + "/link.txt");
  penumbra::write_file(dir + "/link.txt", "new", "text file");
  EXPECT_TRUE(fs::is_symlink(dir + "/link.txt"));
  EXPECT_EQ(read_text(dir + "/real.txt"), "new");
}

TEST(OutputFile, ReplacedFileKeepsItsPermissions) {
  const std::string dir = fresh_dir("mode");
  write_text(dir + "/a.txt", "old");
  fs::permissions(dir + "/a.txt", fs::perms(0640));
  penumbra::write_file(dir + "/a.txt", "new", "text file");
  EXPECT_EQ(fs::status(dir + "/a.txt").permissions(), fs::perms(0640));
}

TEST(OutputFile, SeveralFilesAreWrittenAllOrNone) {
  const std::string dir = fresh_dir("all_or_none");
  write_text(dir + "/a.txt", "old a");
  write_text(dir + "/blocker", "x");
  const std::string message = error_of([&] {
    penumbra::write_files({{dir + "/a.txt", "new a", "text file"},
                           {dir + "/b.txt", "new b", "text file"},
                           {dir + "/blocker/c.txt", "new c", "text file"}});
  });
  EXPECT_NE(message.find("blocker/c.txt"), std::string::npos) << message;
  EXPECT_EQ(read_text(dir + "/a.txt"), "old a");
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"a.txt", "blocker"}));
  penumbra::write_files(
      {{dir + "/a.txt", "new a", "text file"}, {dir + "/b.txt", "new b", "text file"}});
  EXPECT_EQ(read_text(dir + "/a.txt"), "new a");
  EXPECT_EQ(read_text(dir + "/b.txt"), "new b");
}

}  // namespace
