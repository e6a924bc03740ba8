#pragma once
// The registry of temporary files that an interruption removes (interrupt.cpp), as OutputFile
// (output_file.cpp) keeps it.
#include <string>

namespace penumbra::temporary_files {

// While a Change lives, a signal is only noted: the file-system changes made under it and the
// registry's record of them (a temporary file created and listed, renamed and struck off) are
// never cut in half. The interruption happens when the outermost Change ends. A Change begun
// while an interruption removes the files waits for the end of the process.
class Change {
 public:
  Change();
  ~Change();
  Change(const Change&) = delete;
  Change& operator=(const Change&) = delete;
};

// Each under a Change. `destination` is the name the line of an interruption gives.
void add(const std::string& temporary, const std::string& destination);
void remove(const std::string& temporary) noexcept;
void kept(const std::string& destination);  // renamed into place: an output the call finished

// A test's signal (PENUMBRA_TEST_SIGNAL="TERM written:frame_002.png"): raised when `point`
// ("written": the temporary file is whole, "renaming": under the Change of its rename) is
// reached for the file named as given.
void test_signal(const char* point, const std::string& destination);

}  // namespace penumbra::temporary_files
