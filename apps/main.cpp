// `penumbra`: the command-line tool. One file per subcommand; shared options in common.cpp.
// Every failure prints one line `penumbra: error: <message>` to stderr and exits with 1
// (2 for usage errors).
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "common.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/interrupt.hpp"

namespace {

int fail(const std::string& message, int code = 1) {
  std::cerr << "penumbra: error: " << penumbra::cli::one_line(message) << std::endl;
  return code;
}

// What a command printed is written out only when standard output is flushed: a full disk or a
// closed pipe shows up there, and must not end in exit status 0.
int flushed(int code) {
  errno = 0;
  std::cout.flush();
  if (std::fflush(stdout) == 0 && !std::ferror(stdout) && std::cout.good()) return code;
  const int error = errno;
  return code != 0 ? code
                   : fail(std::string("cannot write to standard output") +
                          (error ? std::string(": ") + std::strerror(error) : std::string()));
}

void handle_signals() {
  // A write past a file-size limit (RLIMIT_FSIZE) or into a pipe nobody reads would kill the
  // process with SIGXFSZ or SIGPIPE; ignored, the write fails with EFBIG or EPIPE instead and
  // the file writer reports it as an error.
  std::signal(SIGXFSZ, SIG_IGN);
  std::signal(SIGPIPE, SIG_IGN);
  // SIGINT, SIGTERM, SIGHUP: the temporary files removed, the finished files kept, one line,
  // and the process ended by the signal (penumbra/interrupt.hpp).
  penumbra::install_interrupt_handlers("penumbra");
}

}  // namespace

int main(int argc, char** argv) {
  using namespace penumbra::cli;
  handle_signals();
  // CLBlast's programs released when main returns, before the static destructors run.
  struct ReleaseGemmPrograms {
    ~ReleaseGemmPrograms() { penumbra::release_gemm_programs(); }
  } release_gemm_programs;
  CLI::App app{
      "penumbra: differentiable soft rasterization with shadows on OpenCL (render, gradients, "
      "gradient checks, turnaround animations, fitting shapes to silhouettes and shadows)",
      "penumbra"};
  // Set before the subcommands are added: they inherit it.
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return "penumbra: error: " + one_line(e.what()) + " (see penumbra --help)\n";
  });
  app.require_subcommand(1);

  std::vector<Command> commands;
  try {
    commands.push_back(add_devices_command(app));
    commands.push_back(add_render_command(app));
    commands.push_back(add_backward_command(app));
    commands.push_back(add_gradcheck_command(app));
    commands.push_back(add_turnaround_command(app));
    commands.push_back(add_figures_command(app));
    commands.push_back(add_fit_silhouette_command(app));
    commands.push_back(add_fit_shadows_command(app));
    commands.push_back(add_shadow_art_command(app));
    commands.push_back(add_tune_command(app));
    commands.push_back(add_kernels_command(app));
  } catch (const std::exception& e) {
    return fail(e.what());
  }

  // A first word that is neither an option nor a subcommand: name it (CLI11 would only say that
  // a subcommand is required).
  if (argc > 1 && argv[1][0] != '-') {
    bool known = false;
    for (const Command& command : commands) known = known || command.app->check_name(argv[1]);
    if (!known) {
      return fail(
          std::string("unknown command '") + argv[1] +
              "' (commands: devices, render, backward, gradcheck, turnaround, figures, tune, "
              "kernels, fit-silhouette, fit-shadows, shadow-art; see penumbra --help)",
          2);
    }
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? flushed(0) : 2;
  }

  try {
    for (const Command& command : commands) {
      if (!command.app->parsed()) continue;
      penumbra::set_interrupted_activity(command.app->get_name());
      return flushed(command.run());
    }
    return fail("no subcommand given", 2);
  } catch (const penumbra::Error& e) {
    return fail(e.what());
  } catch (const cl::Error& e) {
    return fail("OpenCL error " + penumbra::opencl_error_name(e.err()) + " (" +
                std::to_string(e.err()) + ") in " + e.what());
  } catch (const CLI::ParseError& e) {
    return fail(e.what(), 2);
  } catch (const std::exception& e) {
    return fail(e.what());
  } catch (...) {
    return fail("unknown exception");
  }
}
