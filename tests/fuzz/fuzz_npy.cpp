// libFuzzer target: load_npy on arbitrary bytes (written to a scratch .npy file). A successful
// load must give a non-negative shape whose product is the number of values (a zero in the
// shape is a legal, empty array, as NumPy writes for an empty gradient).
#include <cstdint>

#include "fuzz_common.hpp"
#include "penumbra/io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace penumbra;
  const std::string path = fuzz::write_input(data, size, "input.npy");
  try {
    const Image image = load_npy(path);
    if (image.width < 0 || image.height < 0 || image.channels < 0) fuzz::broken("negative shape");
    if (image.data.size() != size_t(image.width) * image.height * image.channels)
      fuzz::broken("data size != product of the shape");
  } catch (const Error& e) {
    fuzz::check_error(e);
  }
  return 0;
}
