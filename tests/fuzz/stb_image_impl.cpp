// The stb_image implementation compiled into the image fuzzer, instrumented like the rest of the
// target. Its symbols take precedence over those of the shared libstb the library links.
#define STB_IMAGE_IMPLEMENTATION
#include <stb_image.h>
