// SIGINT, SIGTERM and SIGHUP while the tool writes (penumbra/interrupt.hpp): no temporary file
// stays, the files finished before stay whole, the earlier files at the other destinations stay
// untouched, one line says what was interrupted and kept, and the process ends by the signal
// (a shell reports 130, 143, 129). docs/faults.md lists these cases.
//
// A signal comes at a chosen point either from the test, once a file shows that the tool got
// there, or from the tool itself (PENUMBRA_TEST_SIGNAL="INT written:frame_001.png": when that
// file's temporary is whole; "renaming:NAME": while it is renamed into place).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "cli_run.hpp"
#include "penumbra/image.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "scenes.hpp"

namespace fs = std::filesystem;
using namespace penumbra_tests;

namespace {

const std::string kSmall = " --width 16 --height 16 --map-size 16 --shadows hard";

std::string fresh_dir(const std::string& name) { return fresh_temp_dir("interrupt_" + name); }

// Every temporary file (.NAME.PID.N.tmp) under `dir`.
std::vector<std::string> temporaries(const std::string& dir) {
  std::vector<std::string> found;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    const std::string name = entry.path().filename();
    if (name.size() > 4 && name.compare(name.size() - 4, 4, ".tmp") == 0) found.push_back(name);
  }
  return found;
}

// Starts `sh -c command` with SIGINT, SIGTERM and SIGHUP at their default actions (a test runner
// started in the background of a script has SIGINT ignored, which the tool would respect).
pid_t start_shell(const std::string& command, const std::string& test_signal = "") {
  const pid_t pid = ::fork();
  if (pid == 0) {
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) ::signal(sig, SIG_DFL);
    if (!test_signal.empty()) ::setenv("PENUMBRA_TEST_SIGNAL", test_signal.c_str(), 1);
    ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

int shell(const std::string& command) {
  int status = -1;
  ::waitpid(start_shell(command), &status, 0);
  return status;
}

// The tool started in the background, stdout to /dev/null and stderr to a file (an earlier run's
// removed first: the test watches it); `exec`, so that a signal sent to the child reaches the
// tool itself.
class Background {
 public:
  Background(const std::string& args, const std::string& err, const std::string& test_signal = "")
      : err_(err) {
    fs::remove(err);
    pid_ = start_shell("exec " + quote(PENUMBRA_CLI) + " " + args + " >/dev/null 2>" + quote(err),
                       test_signal);
  }
  Background(const Background&) = delete;
  Background& operator=(const Background&) = delete;
  ~Background() {
    if (status_ < 0) ::kill(pid_, SIGKILL), wait();
  }

  // Polls `ready` until it holds; false when the tool ended first or after five minutes.
  bool wait_until(const std::function<bool()>& ready) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::minutes(5);
    while (std::chrono::steady_clock::now() < end) {
      if (ready()) return true;
      if (::waitpid(pid_, &status_, WNOHANG) == pid_) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  }
  void send(int sig) const { ::kill(pid_, sig); }
  int wait() {
    if (status_ < 0) ::waitpid(pid_, &status_, 0);
    return status_;
  }
  std::string err() const { return read_text(err_); }

 private:
  pid_t pid_ = -1;
  int status_ = -1;
  std::string err_;
};

const char* name_of(int sig) {
  return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "SIGHUP";
}

// The run ended by `sig`, and the last line on stderr says so: returns that line.
std::string expect_ended_by(Background& run, int sig, const std::string& command) {
  const int status = run.wait();
  const std::string err = run.err();
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig)
      << "status " << status << ", stderr:\n"
      << err;
  const std::vector<std::string> all = lines(err);
  std::string last = all.empty() ? "" : all.back();
  const std::string start =
      std::string("penumbra: interrupted by ") + name_of(sig) + " during " + command + "; ";
  EXPECT_EQ(last.rfind(start, 0), 0u) << err;
  return last;
}

std::string run_until_signalled(const std::string& args, const std::string& dir, int sig,
                                const std::string& point, const std::string& command) {
  // "INT written:frame_001.png"
  Background run(args, dir + ".stderr", std::string(name_of(sig)).substr(3) + " " + point);
  return expect_ended_by(run, sig, command);
}

bool whole_png(const std::string& path) {
  try {
    return penumbra::load_image(path).width == 16;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

// The frame loop, from outside: each frame on disk is whole, the GIF being written is gone.
TEST(Interrupt, TurnaroundFrameLoopFromOutside) {
  for (int sig : {SIGINT, SIGTERM}) {
    const std::string dir = fresh_dir(std::string("loop_") + name_of(sig));
    Background run("turnaround --frames 400 -o " + quote(dir) + kSmall, dir + ".stderr");
    ASSERT_TRUE(run.wait_until([&] { return fs::exists(dir + "/frame_001.png"); })) << run.err();
    run.send(sig);
    const std::string line = expect_ended_by(run, sig, "turnaround");
    EXPECT_EQ(temporaries(dir), std::vector<std::string>{}) << line;
    EXPECT_FALSE(fs::exists(dir + "/turnaround.gif"));
    int frames = 0;  // each whole
    for (const auto& entry : fs::directory_iterator(dir)) {
      EXPECT_EQ(entry.path().filename().string().rfind("frame_", 0), 0u) << entry.path();
      EXPECT_TRUE(whole_png(entry.path())) << entry.path();
      ++frames;
    }
    ASSERT_GE(frames, 2);
    ASSERT_LT(frames, 400);
    EXPECT_NE(line.find("; kept the " + std::to_string(frames) + " files it finished, the last " +
                        dir + "/frame_"),
              std::string::npos)
        << line;
  }
}

// A frame's temporary file is whole but not yet in place: it goes, with the GIF being written.
TEST(Interrupt, TurnaroundBetweenAFrameAndItsRename) {
  const std::string dir = fresh_dir("frame");
  const std::string line = run_until_signalled("turnaround --frames 3 -o " + quote(dir) + kSmall,
                                               dir, SIGINT, "written:frame_001.png", "turnaround");
  EXPECT_EQ(line,
            "penumbra: interrupted by SIGINT during turnaround; removed 2 unfinished files (" +
                dir + "/turnaround.gif, ...); kept " + dir + "/frame_000.png");
  EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
  EXPECT_TRUE(whole_png(dir + "/frame_000.png"));
  EXPECT_FALSE(fs::exists(dir + "/frame_001.png"));
}

// The whole GIF, before its rename: the GIF of an earlier run stays; every frame stays.
TEST(Interrupt, TurnaroundGifBeforeItsRename) {
  const std::string dir = fresh_dir("gif");
  write_text(dir + "/turnaround.gif", "earlier");
  const std::string line =
      run_until_signalled("turnaround --frames 3 -o " + quote(dir) + kSmall, dir, SIGTERM,
                          "written:turnaround.gif", "turnaround");
  EXPECT_EQ(line, "penumbra: interrupted by SIGTERM during turnaround; removed the unfinished " +
                      dir + "/turnaround.gif; kept the 3 files it finished, the last " + dir +
                      "/frame_002.png");
  EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
  EXPECT_EQ(read_text(dir + "/turnaround.gif"), "earlier");
  for (const char* f : {"/frame_000.png", "/frame_001.png", "/frame_002.png"})
    EXPECT_TRUE(whole_png(dir + f)) << f;
}

// render --raw writes its files as one: a signal before the renames leaves the earlier files,
// one during them waits until every file is in place.
TEST(Interrupt, RenderRawArraysAreAllOrNone) {
  for (const char* point : {"written:depth.npy", "renaming:silhouette.npy"}) {
    const bool renaming = std::string(point).rfind("renaming", 0) == 0;
    const std::string dir = fresh_dir(renaming ? "raw_renaming" : "raw_written");
    fs::create_directories(dir + "/raw");
    for (const char* f : {"/out.png", "/raw/color.npy", "/raw/depth.npy"})
      write_text(dir + f, "earlier");
    const int sig = renaming ? SIGTERM : SIGINT;
    const std::string line = run_until_signalled(
        "render -o " + quote(dir + "/out.png") + " --raw " + quote(dir + "/raw") + kSmall, dir, sig,
        point, "render");
    EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
    if (renaming) {
      EXPECT_EQ(line, std::string("penumbra: interrupted by SIGTERM during render; no file was "
                                  "being written; kept the 5 files it finished, the last ") +
                          dir + "/raw/shadow_map_0.npy");
      EXPECT_TRUE(whole_png(dir + "/out.png"));
      for (const char* f :
           {"/raw/color.npy", "/raw/silhouette.npy", "/raw/depth.npy", "/raw/shadow_map_0.npy"})
        EXPECT_NO_THROW(penumbra::load_npy(dir + f)) << f;
    } else {
      EXPECT_EQ(line,
                "penumbra: interrupted by SIGINT during render; removed 4 unfinished files (" +
                    dir + "/out.png, ...); no file was finished");
      for (const char* f : {"/out.png", "/raw/color.npy", "/raw/depth.npy"})
        EXPECT_EQ(read_text(dir + f), "earlier") << f;
      EXPECT_FALSE(fs::exists(dir + "/raw/silhouette.npy"));
    }
  }
}

// backward's gradients, likewise; SIGHUP (the terminal closed) as well.
TEST(Interrupt, BackwardGradientsAreAllOrNone) {
  const std::string grads = fresh_dir("grad_in");
  penumbra::save_npy(penumbra::Image(16, 16, 3, 1.0), grads + "/color.npy");
  for (int sig : {SIGTERM, SIGHUP}) {
    const std::string point = sig == SIGTERM ? "written:lights.npy" : "renaming:ambient.npy";
    const std::string dir = fresh_dir(std::string("backward_") + name_of(sig));
    write_text(dir + "/lights.npy", "earlier");
    const std::string line =
        run_until_signalled("backward --grad-in " + quote(grads) + " -o " + quote(dir) + kSmall,
                            dir, sig, point, "backward");
    EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
    if (sig == SIGHUP) {
      EXPECT_NE(line.find("; no file was being written; kept the "), std::string::npos) << line;
      EXPECT_EQ(line.substr(line.rfind(" the last ")), " the last " + dir + "/ambient.npy");
      EXPECT_NE(read_text(dir + "/lights.npy"), "earlier");
    } else {
      EXPECT_NE(line.find(" unfinished files ("), std::string::npos) << line;
      EXPECT_EQ(line.substr(line.rfind("; ")), "; no file was finished");
      EXPECT_EQ(read_text(dir + "/lights.npy"), "earlier");
      EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
    }
  }
}

// tune holds no temporary file while it tunes, and a signal then leaves nothing; one at the end,
// when the database is whole but not in place, leaves the earlier database.
TEST(Interrupt, TuneLeavesNoDatabaseHalfWritten) {
  const std::string dir = fresh_dir("tune");
  const std::string tune = "tune --quick --runs 1 -o " + quote(dir + "/db.json");
  {
    Background run(tune, dir + "_tuning.stderr");
    ASSERT_TRUE(run.wait_until([&] { return run.err().find("tuning on ") != std::string::npos; }))
        << run.err();
    EXPECT_EQ(temporaries(dir), std::vector<std::string>{});  // none held while tuning
    run.send(SIGTERM);
    const std::string line = expect_ended_by(run, SIGTERM, "tune");
    // (a kernel-cache entry being written may have gone; it is not the call's output)
    EXPECT_EQ(line.substr(line.rfind("; ")), "; no file was finished");
    EXPECT_EQ(line.find("db.json"), std::string::npos) << line;
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 0);
  }
  write_text(dir + "/db.json", "{\"version\": 1, \"entries\": {}}\n");
  const std::string before = read_text(dir + "/db.json");
  const std::string line = run_until_signalled(tune, dir, SIGINT, "written:db.json", "tune");
  EXPECT_EQ(line, "penumbra: interrupted by SIGINT during tune; removed the unfinished " + dir +
                      "/db.json; no file was finished");
  EXPECT_EQ(read_text(dir + "/db.json"), before);
  EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
}

namespace {

// The iteration of DIR/checkpoint.json, -1 while there is none.
int checkpoint_iteration(const std::string& dir) {
  const std::string text = read_text(dir + "/checkpoint.json");
  return text.empty() ? -1 : nlohmann::json::parse(text).at("iteration").get<int>();
}

// A fit interrupted mid-way goes on with --resume to its last iteration.
void expect_resumes(const std::string& fit, const std::string& dir, const std::string& command,
                    int iterations) {
  const RunResult r = run_cli_to(fit + " --resume -o " + quote(dir), dir + ".out", dir + ".err2");
  ASSERT_EQ(r.exit_code, 0) << show(r);
  EXPECT_EQ(
      lines(r.out).back().rfind(command + ": iterations=" + std::to_string(iterations) + " ", 0),
      0u)
      << show(r);
}

}  // namespace

// The fits from outside, mid-way: the GIF being written goes, the checkpoint stays and resumes.
TEST(Interrupt, FitsMidWayKeepAResumableCheckpoint) {
  struct Case {
    std::string command;
    int sig, iterations;
  };
  for (const Case& c : {Case{"fit-silhouette", SIGINT, 40}, Case{"fit-shadows", SIGTERM, 24}}) {
    const std::string dir = fresh_dir(c.command);
    const std::string fit = c.command + " --iterations " + std::to_string(c.iterations) +
                            " --checkpoint-every 4 --gif-every 2";
    Background run(fit + " -o " + quote(dir), dir + ".stderr");
    ASSERT_TRUE(run.wait_until([&] { return checkpoint_iteration(dir) >= 8; })) << run.err();
    run.send(c.sig);
    const std::string line = expect_ended_by(run, c.sig, c.command);
    EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
    EXPECT_NE(line.find(dir + "/fit.gif"), std::string::npos) << line;  // removed
    EXPECT_FALSE(fs::exists(dir + "/fit.gif"));
    EXPECT_EQ(line.substr(line.rfind("; ")), "; --resume goes on from " + dir + "/checkpoint.json");
    const int at = checkpoint_iteration(dir);
    EXPECT_LT(at, c.iterations);
    if (c.command == "fit-silhouette") expect_resumes(fit, dir, c.command, c.iterations);
  }
}

// A signal while a checkpoint is renamed into place waits for it: that checkpoint resumes. One
// before the first checkpoint is in place leaves none, and the line does not offer --resume.
TEST(Interrupt, FitCheckpointIsWholeOrAbsent) {
  const std::string fit = "shadow-art --iterations 6 --checkpoint-every 2";
  const std::string kept = fresh_dir("art_renaming");
  const std::string line = run_until_signalled(fit + " -o " + quote(kept), kept, SIGINT,
                                               "renaming:checkpoint.json", "shadow-art");
  EXPECT_EQ(line.substr(line.rfind("; ")), "; --resume goes on from " + kept + "/checkpoint.json");
  EXPECT_EQ(checkpoint_iteration(kept), 2);
  EXPECT_EQ(temporaries(kept), std::vector<std::string>{});
  expect_resumes(fit, kept, "shadow-art", 6);

  const std::string none = fresh_dir("art_written");
  const std::string line2 = run_until_signalled(fit + " -o " + quote(none), none, SIGTERM,
                                                "written:checkpoint.json", "shadow-art");
  EXPECT_EQ(line2.find("--resume"), std::string::npos) << line2;
  EXPECT_FALSE(fs::exists(none + "/checkpoint.json"));
  EXPECT_EQ(temporaries(none), std::vector<std::string>{});
}

// What a shell reports: 128 + the signal. A signal the tool was started with ignored (nohup,
// `trap '' TERM`) stays ignored, and the call finishes.
TEST(Interrupt, ShellSeesTheSignalAndAnIgnoredSignalStaysIgnored) {
  const std::string dir = fresh_dir("shell");
  const std::string render = quote(PENUMBRA_CLI) + " render -o " + quote(dir + "/out.png") + kSmall;
  for (const auto& [sig, status] :
       {std::pair<std::string, std::string>{"INT", "130"}, {"TERM", "143"}}) {
    const std::string out = dir + ".out";
    const int rc = shell("PENUMBRA_TEST_SIGNAL='" + sig + " written:out.png' " + render +
                         " 2>/dev/null; echo $? >" + quote(out));
    ASSERT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << rc;
    EXPECT_EQ(read_text(out), status + "\n") << sig;
  }
  EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
  EXPECT_FALSE(fs::exists(dir + "/out.png"));
  const int rc = shell("trap '' TERM; PENUMBRA_TEST_SIGNAL='TERM written:out.png' " + render +
                       " >/dev/null 2>&1");
  EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << rc;
  EXPECT_TRUE(whole_png(dir + "/out.png"));
}
