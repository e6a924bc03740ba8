#pragma once
// What an interrupted program leaves. With the handlers installed, SIGINT, SIGTERM or SIGHUP at
// any moment removes the temporary file of every OutputFile (io.hpp) not yet renamed into place,
// keeps every file already renamed (and the earlier files at the other destinations), prints one
// line on stderr,
//   penumbra: interrupted by SIGINT during turnaround; removed the unfinished out/turnaround.gif;
//   kept the 12 files it finished, the last out/frame_011.png
// and ends the process by the same signal, as its default action would (a shell reports
// 128 + N: 130, 143, 129). A signal that comes while a file is being renamed into place (or
// several files as one, write_files) waits until the rename is done, so that a set of files is
// still all or none. The handlers end the process at once, even during a long OpenCL wait.
#include <string>

namespace penumbra {

// Installs the handlers (once, early in main). `program` starts the line.
void install_interrupt_handlers(const std::string& program);
// What runs, named in the line ("turnaround"); "" names nothing.
void set_interrupted_activity(const std::string& what);
// Said at the end of the line ("--resume goes on from DIR/checkpoint.json"); "" says nothing.
// With `once_kept`, only once that file has been renamed into place by this process.
void set_interrupted_note(const std::string& note, const std::string& once_kept = "");

}  // namespace penumbra
