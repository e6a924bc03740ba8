// libFuzzer target: load_image on arbitrary bytes (written to a scratch file), with the file's
// own channel count and then, if that succeeds, with 1 to 4 channels requested. A successful
// load must give width × height × channels values, each in [0, 1] for 8- and 16-bit formats.
// stb_image is compiled into this target from its header (stb_image_impl.cpp), instrumented,
// so that the fuzzer sees its branches and the sanitizers its memory accesses.
#include <cmath>
#include <cstdint>

#include "fuzz_common.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"

namespace {

void check_image(const penumbra::Image& image, int want_channels, bool unit_range) {
  using penumbra::fuzz::broken;
  if (image.width <= 0 || image.height <= 0) broken("loaded image has no pixels");
  if (want_channels > 0 && image.channels != want_channels) broken("wrong channel count");
  if (image.data.size() != size_t(image.width) * image.height * image.channels)
    broken("image data size != width * height * channels");
  if (unit_range)
    for (double v : image.data)
      if (!(v >= 0.0 && v <= 1.0)) broken("8/16-bit image value outside [0, 1]");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace penumbra;
  const std::string path = fuzz::write_input(data, size, "input.img");
  // Radiance HDR files start with "#?"; every other format stb reads is 8 or 16 bits.
  const bool hdr = size >= 2 && data[0] == '#' && data[1] == '?';
  try {
    check_image(load_image(path), 0, !hdr);
    const int channels = 1 + int(size % 4);
    check_image(load_image(path, channels), channels, !hdr);
  } catch (const Error& e) {
    fuzz::check_error(e);
  }
  return 0;
}
