#pragma once
// Running the `penumbra` tool (PENUMBRA_CLI) as a child process from the tests, with stdout and
// stderr captured in files, and the checks made on its result. Header-only: each test file keeps
// its own temporary-file names (ctest runs tests in parallel processes).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace penumbra_tests {

struct RunResult {
  bool signaled = false;  // killed by a signal (directly, or as reported by the shell)
  int exit_code = -1;
  std::string out, err, command;
};

// `s` in single quotes for the shell.
// Sets (or, with nullptr, removes) an environment variable until the end of the scope; a
// process started meanwhile (the CLI) inherits it.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = std::make_unique<std::string>(old);
    value ? setenv(name, value, 1) : unsetenv(name);
  }
  ScopedEnv(const char* name, const std::string& value) : ScopedEnv(name, value.c_str()) {}
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;
  ~ScopedEnv() { old_ ? setenv(name_, old_->c_str(), 1) : unsetenv(name_); }

 private:
  const char* name_;
  std::unique_ptr<std::string> old_;
};

inline std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

inline std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> result;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) result.push_back(line);
  return result;
}

// Runs `penumbra <args>` with stdout in the file `out` and stderr in `err`.
inline RunResult run_cli_to(const std::string& args, const std::string& out,
                            const std::string& err) {
  RunResult r;
  r.command = quote(PENUMBRA_CLI) + " " + args;
  const int status = std::system((r.command + " >" + quote(out) + " 2>" + quote(err)).c_str());
  if (status == -1 || WIFSIGNALED(status)) {
    r.signaled = true;
  } else if (WIFEXITED(status)) {
    r.exit_code = WEXITSTATUS(status);
    // A shell reports a child killed by signal N as exit status 128 + N.
    r.signaled = r.exit_code >= 128;
  }
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

inline std::string show(const RunResult& r) {
  return "command: " + r.command + "\nexit: " + std::to_string(r.exit_code) +
         (r.signaled ? " (signal)" : "") + "\nstdout:\n" + r.out + "\nstderr:\n" + r.err;
}

// The contract for every failure: a non-zero exit status (not a signal) and exactly one line on
// stderr starting with "penumbra: error:" that mentions `mentions`.
inline void expect_clean_error(const RunResult& r, const std::string& mentions = "") {
  EXPECT_FALSE(r.signaled) << show(r);
  EXPECT_NE(r.exit_code, 0) << show(r);
  const auto err = lines(r.err);
  ASSERT_EQ(err.size(), 1u) << "expected exactly one line on stderr\n" << show(r);
  EXPECT_EQ(err[0].rfind("penumbra: error:", 0), 0u) << show(r);
  if (!mentions.empty()) {
    EXPECT_NE(err[0].find(mentions), std::string::npos)
        << "the message should mention '" << mentions << "'\n"
        << show(r);
  }
}

}  // namespace penumbra_tests
