// Errors: every failure reaches the caller as one penumbra::Error with a one-line message that
// names the problem.
//
//   ErrorsKernel.*    a kernel that fails to build carries the compiler's message; kernel
//                     arguments that do not fit the kernel are refused before it runs
//   ErrorsDevice.*    unknown device names and indices; double precision without cl_khr_fp64
//   ErrorsBackward.*  gradient images of the wrong size or count, backward before render
//   ErrorsFuzz.*      inputs found by the fuzzers (tests/fuzz) — each once a memory error,
//                     a sanitizer report, an escaped exception, a huge allocation or a
//                     multi-line message of a loader — now a clean penumbra::Error
// A missing OpenCL device fails the device tests; it never skips them.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "ops/args.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/image.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace {

using glm::dvec3;
using penumbra::Context;
using penumbra::Error;
using penumbra::Image;
using penumbra::Mesh;
using penumbra::OutputGrads;
using penumbra::Precision;
using penumbra::Renderer;
using penumbra::RenderOutput;
using penumbra::Scene;
using penumbra::Shadows;
using penumbra_tests::ScopedEnv;

namespace fs = std::filesystem;

const std::string kSourceDir = fs::path(PENUMBRA_DATA_DIR).parent_path().string();

// Runs `fn` and returns the message of the penumbra::Error it throws; fails the test when it
// throws nothing, throws something else, or the message spans lines.
std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "message spans lines: " << msg;
    return msg;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected penumbra::Error, got another exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected penumbra::Error, nothing was thrown";
  return {};
}

#define EXPECT_CONTAINS(text, needle)                          \
  EXPECT_NE(std::string(text).find(needle), std::string::npos) \
      << "\"" << (text) << "\" lacks \"" << (needle) << "\""

// A tetrahedron above a ground quad, one small camera, one point light.
Scene small_scene(Shadows shadows = Shadows::None) {
  Scene s;
  Mesh tet;
  tet.name = "tetra";
  tet.vertices = {{-0.5, 0.3, -0.4}, {0.5, 0.3, -0.4}, {0.0, 0.3, 0.5}, {0.0, 1.1, 0.0}};
  tet.faces = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}};
  tet.albedo.assign(4, dvec3(0.8, 0.5, 0.3));
  Mesh ground;
  ground.name = "ground";
  ground.vertices = {{-2, 0, -2}, {2, 0, -2}, {2, 0, 2}, {-2, 0, 2}};
  ground.faces = {{0, 2, 1}, {0, 3, 2}};
  ground.albedo.assign(4, dvec3(0.7));
  s.meshes = {tet, ground};
  penumbra::Camera cam;
  cam.eye = {0.5, 2.5, 3.5};
  cam.target = {0, 0.3, 0};
  cam.near = 0.5;
  cam.far = 10;
  cam.width = 24;
  cam.height = 20;
  s.cameras = {cam};
  penumbra::Light light;
  light.position = {1, 4, 1};
  light.size = 0.2;
  s.lights = {light};
  s.params.sigma = 1e-4;
  s.params.gamma = 1e-3;
  s.params.shadows = shadows;
  s.params.shadow_map_size = 32;
  penumbra::fit_light_frusta(s);
  return s;
}

// ---- kernels --------------------------------------------------------------------------------

// A copy of kernels/ with a syntax error at the top of raster.cl: rendering builds the raster
// program, and the error must name the file, say it failed to build, and quote the compiler.
TEST(ErrorsKernel, BuildFailureCarriesCompilerLog) {
  const fs::path dir = fs::path(::testing::TempDir()) / "penumbra_errors_kernels";
  fs::remove_all(dir);
  fs::copy(fs::path(kSourceDir) / "kernels", dir, fs::copy_options::recursive);
  {
    std::ifstream in(dir / "raster.cl");
    std::stringstream text;
    text << in.rdbuf();
    in.close();
    std::ofstream out(dir / "raster.cl", std::ios::trunc);
    out << "penumbra_injected_syntax_error here;\n" << text.str();
  }
  ScopedEnv env("PENUMBRA_KERNEL_DIR", dir.string());
  Context ctx;  // its own program cache: nothing built before the variable was set
  Renderer renderer(ctx, Precision::Float);
  const Scene scene = small_scene();
  const std::string msg = error_of([&] { renderer.render(scene); });
  EXPECT_CONTAINS(msg, "raster.cl");
  EXPECT_CONTAINS(msg, "failed to build");
  EXPECT_CONTAINS(msg, "penumbra_injected_syntax_error");  // quoted by the compiler's message
  EXPECT_CONTAINS(msg, "error");
}

TEST(ErrorsKernel, MissingKernelDirectoryFile) {
  const fs::path dir = fs::path(::testing::TempDir()) / "penumbra_errors_empty_kernels";
  fs::create_directories(dir);
  ScopedEnv env("PENUMBRA_KERNEL_DIR", dir.string());
  Context ctx;
  Renderer renderer(ctx, Precision::Float);
  const Scene scene = small_scene();
  const std::string msg = error_of([&] { renderer.render(scene); });
  EXPECT_CONTAINS(msg, "not found in PENUMBRA_KERNEL_DIR");
}

// A kernel of three arguments in a kernel directory of its own, built through the Context as
// the renderer's are, and argument structs that fit it or do not.
struct TinyKernel {
  static constexpr const char* kSource =
      "__kernel void tiny(__global float* out, int n, float scale) {\n"
      "  int i = get_global_id(0);\n"
      "  if (i < n) out[i] = scale * i;\n"
      "}\n";
  TinyKernel() : env("PENUMBRA_KERNEL_DIR", dir().string()), kernels(ctx, Precision::Float, {}) {}
  static fs::path dir() {  // a folder per test: ctest runs the tests side by side
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    fs::path d =
        fs::path(::testing::TempDir()) /
        ("penumbra_tiny_kernel_" + std::string(test->test_suite_name()) + "_" + test->name());
    fs::create_directories(d);
    std::ofstream out(d / "tiny.cl", std::ios::trunc);
    out << kSource;
    EXPECT_TRUE(out.flush().good()) << "cannot write " << (d / "tiny.cl").string();
    return d;
  }
  ScopedEnv env;
  Context ctx;  // its own program cache, reading the directory above
  penumbra::detail::Kernels kernels;
};

struct TinyArgs {
  static constexpr const char* file = "tiny.cl";
  static constexpr const char* kernel = "tiny";
  const cl::Buffer& out;
  cl_int n;
  penumbra::detail::Real scale;
  auto fields() const { return std::tie(out, n, scale); }
};

struct TinyArgsShort {  // scale left out
  static constexpr const char* file = "tiny.cl";
  static constexpr const char* kernel = "tiny";
  const cl::Buffer& out;
  cl_int n;
  auto fields() const { return std::tie(out, n); }
};

struct TinyArgsSwapped {  // n and out swapped
  static constexpr const char* file = "tiny.cl";
  static constexpr const char* kernel = "tiny";
  cl_int n;
  const cl::Buffer& out;
  penumbra::detail::Real scale;
  auto fields() const { return std::tie(n, out, scale); }
};

TEST(ErrorsKernel, FittingArgumentsRun) {
  TinyKernel t;
  cl::Buffer out = penumbra::detail::alloc_reals(t.ctx, Precision::Float, 8);
  auto& k = penumbra::detail::bind_args(t.kernels, TinyArgs{out, 8, 0.5});
  penumbra::detail::launch_1d(t.ctx, k, 8);
  const auto v = penumbra::detail::download_reals(t.ctx, Precision::Float, out, 8);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(v[i], 0.5 * i);
}

// The count is checked on every device: the message names the kernel, its file and both counts.
TEST(ErrorsKernel, ArgumentCountMismatch) {
  TinyKernel t;
  cl::Buffer out = penumbra::detail::alloc_reals(t.ctx, Precision::Float, 8);
  const std::string msg = error_of([&] {
    penumbra::detail::bind_args(t.kernels, TinyArgsShort{out, 8});
  });
  EXPECT_CONTAINS(msg, "kernel 'tiny' of tiny.cl");
  EXPECT_CONTAINS(msg, "the host binds 2 arguments, the kernel takes 3");
}

// A buffer where the kernel takes a number: refused by the kind check where the device reports
// address qualifiers, else by clSetKernelArg (a pointer's size is not an int's).
TEST(ErrorsKernel, ArgumentKindMismatch) {
  TinyKernel t;
  cl::Buffer out = penumbra::detail::alloc_reals(t.ctx, Precision::Float, 8);
  const std::string msg = error_of([&] {
    penumbra::detail::bind_args(t.kernels, TinyArgsSwapped{8, out, 0.5});
  });
  EXPECT_CONTAINS(msg, "kernel 'tiny' of tiny.cl");
  EXPECT_CONTAINS(msg, "argument 0");
}

// ---- devices --------------------------------------------------------------------------------

TEST(ErrorsDevice, UnknownName) {
  const std::string msg = error_of([] { Context ctx("no-such-opencl-device-xyzzy"); });
  EXPECT_CONTAINS(msg, "no OpenCL device matches 'no-such-opencl-device-xyzzy'");
}

TEST(ErrorsDevice, IndexOutOfRange) {
  const std::string msg = error_of([] { Context ctx("4096"); });
  EXPECT_CONTAINS(msg, "device index 4096 out of range");
}

TEST(ErrorsDevice, UnknownNameFromEnvironment) {
  ScopedEnv env("PENUMBRA_DEVICE", "no-such-opencl-device-from-env");
  const std::string msg = error_of([] { Context ctx; });
  EXPECT_CONTAINS(msg, "no-such-opencl-device-from-env");
}

TEST(ErrorsDevice, TransfersFromEnvironmentMustBeMapOrCopy) {
  ScopedEnv env("PENUMBRA_TRANSFERS", "pinned");
  const std::string msg = error_of([] { Context ctx; });
  EXPECT_CONTAINS(msg, "PENUMBRA_TRANSFERS must be map or copy, not 'pinned'");
}

// A device without cl_khr_fp64, simulated: the Context's description of the device is the one
// place the library reads fp64 from, so clearing it there makes the device look like one
// without double precision (the Context object itself is not const, so this is well defined).
TEST(ErrorsDevice, DoubleWithoutFp64) {
  Context ctx;
  const_cast<penumbra::DeviceInfo&>(ctx.info()).fp64 = false;
  const std::string msg = error_of([&] { Renderer renderer(ctx, Precision::Double); });
  EXPECT_CONTAINS(msg, "has no double precision");
  EXPECT_CONTAINS(msg, "cl_khr_fp64");
  // The program cache refuses double-precision programs too.
  const std::string msg2 = error_of([&] { ctx.program("raster.cl", "-DPENUMBRA_DOUBLE=1"); });
  EXPECT_CONTAINS(msg2, "has no double precision");
  // Float still works on that device.
  Renderer renderer(ctx, Precision::Float);
  EXPECT_EQ(renderer.render(small_scene()).size(), 1u);
}

// ---- backward -------------------------------------------------------------------------------

class ErrorsBackward : public ::testing::Test {
 protected:
  static Context& context() {
    static Context ctx;
    return ctx;
  }
};

TEST_F(ErrorsBackward, WrongGradientImageSizes) {
  Renderer renderer(context(), Precision::Float);
  const Scene scene = small_scene(Shadows::Hard);
  const std::vector<RenderOutput> out = renderer.render(scene);
  ASSERT_EQ(out.size(), 1u);
  const int W = out[0].color.width, H = out[0].color.height;

  {
    std::vector<OutputGrads> g(1);
    g[0].color = Image(W + 1, H, 3, 1.0);
    const std::string msg = error_of([&] { renderer.backward(scene, g); });
    EXPECT_CONTAINS(msg, "gradient of color for camera 0");
    EXPECT_CONTAINS(msg, std::to_string(W + 1) + "x" + std::to_string(H) + "x3");
    EXPECT_CONTAINS(msg, "expected " + std::to_string(W) + "x" + std::to_string(H) + "x3");
  }
  {
    std::vector<OutputGrads> g(1);
    g[0].silhouette = Image(W, H, 3, 1.0);  // one channel expected
    const std::string msg = error_of([&] { renderer.backward(scene, g); });
    EXPECT_CONTAINS(msg, "silhouette");
    EXPECT_CONTAINS(msg, "expected " + std::to_string(W) + "x" + std::to_string(H) + "x1");
  }
  {
    std::vector<OutputGrads> g(1);
    g[0].depth = Image(W, H - 1, 1, 1.0);
    const std::string msg = error_of([&] { renderer.backward(scene, g); });
    EXPECT_CONTAINS(msg, "depth");
  }
  {
    std::vector<OutputGrads> g(1);
    g[0].color = Image(W, H, 3, 1.0);
    g[0].color.data.pop_back();  // dimensions right, data short
    const std::string msg = error_of([&] { renderer.backward(scene, g); });
    EXPECT_CONTAINS(msg, "gradient of color");
  }
  {
    std::vector<OutputGrads> g(2);  // one camera, two gradients
    const std::string msg = error_of([&] { renderer.backward(scene, g); });
    EXPECT_CONTAINS(msg, "got gradients for 2 camera(s), the scene has 1");
  }
  // Correct sizes still work after the failures.
  std::vector<OutputGrads> g(1);
  g[0].color = Image(W, H, 3, 1.0);
  const penumbra::SceneGrads grads = renderer.backward(scene, g);
  EXPECT_EQ(grads.vertices.size(), scene.meshes.size());
}

TEST_F(ErrorsBackward, BeforeRenderOrOnAnotherScene) {
  Renderer renderer(context(), Precision::Float);
  const Scene scene = small_scene();
  std::vector<OutputGrads> g(1);
  EXPECT_CONTAINS(error_of([&] { renderer.backward(scene, g); }), "call render() first");
  renderer.render(scene);
  Scene moved = scene;
  moved.meshes[0].vertices[3].y += 0.1;
  EXPECT_CONTAINS(error_of([&] { renderer.backward(moved, g); }), "call render() first");
  Scene recoloured = scene;
  recoloured.meshes[0].albedo.edit([](std::vector<glm::dvec3>& a) { a[0].x *= 0.5; });
  EXPECT_CONTAINS(error_of([&] { renderer.backward(recoloured, g); }), "call render() first");
  Scene turned = scene;
  turned.cameras[0].eye.x += 0.1;
  EXPECT_CONTAINS(error_of([&] { renderer.backward(turned, g); }), "call render() first");
  Scene dimmer = scene;
  dimmer.ambient *= 0.5;
  EXPECT_CONTAINS(error_of([&] { renderer.backward(dimmer, g); }), "call render() first");
  g[0].color = Image(scene.cameras[0].width, scene.cameras[0].height, 3, 1.0);
  EXPECT_NO_THROW(renderer.backward(scene, g));  // the scene rendered
}

TEST_F(ErrorsBackward, InvalidSceneIsRefusedBeforeRendering) {
  Renderer renderer(context(), Precision::Float);
  Scene scene = small_scene();
  scene.params.sigma = 1.5;
  EXPECT_CONTAINS(error_of([&] { renderer.render(scene); }), "sigma");
  scene = small_scene();
  scene.cameras[0].width = 0;
  EXPECT_CONTAINS(error_of([&] { renderer.render(scene); }), "image size");
}

// ---- inputs found by the fuzzers ------------------------------------------------------------
// Each reads its reproducer from tests/fuzz/<target>/regression-* (made by make_seeds.py), the
// same file every fuzzing run replays.

std::string fuzz_input(const std::string& target, const std::string& name) {
  return (fs::path(kSourceDir) / "tests" / "fuzz" / target / name).string();
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  EXPECT_TRUE(in.good() || in.eof()) << "cannot read " << path;
  return s.str();
}

// Scenes name tetra.obj; parse them against a folder that holds one, the process's own (ctest
// runs tests in parallel processes: one rewriting a shared file let another read it empty).
std::string scene_dir() {
  const fs::path dir =
      fs::path(::testing::TempDir()) / ("penumbra_errors_scene_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "tetra.obj")
      << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  return dir.string();
}

// A number beyond double's range escaped parse_scene as nlohmann's out_of_range exception.
TEST(ErrorsFuzz, SceneNumberOverflow) {
  const std::string text = read_file(fuzz_input("scene", "regression-number-overflow.json"));
  const std::string msg = error_of([&] { penumbra::parse_scene(text, scene_dir()); });
  EXPECT_CONTAINS(msg, "invalid JSON");
  EXPECT_CONTAINS(msg, "number overflow");
  // The same through load_scene, and for a value nested anywhere.
  const std::string path = scene_dir() + "/overflow.json";
  std::ofstream(path)
      << R"({"meshes": [{"file": "tetra.obj"}], "cameras": [{}], "ambient": -1e999})";
  EXPECT_CONTAINS(error_of([&] { penumbra::load_scene(path); }), "number overflow");
}

// Strings of the document (values, keys) with line breaks were quoted verbatim.
TEST(ErrorsFuzz, SceneMessagesStayOnOneLine) {
  for (const char* name : {"regression-newline-in-string.json", "regression-newline-in-key.json"}) {
    SCOPED_TRACE(name);
    const std::string text = read_file(fuzz_input("scene", name));
    const std::string msg = error_of([&] { penumbra::parse_scene(text, scene_dir()); });
    EXPECT_CONTAINS(msg, "\\n");  // the line break, escaped
  }
  const std::string msg = error_of([&] {
    penumbra::parse_scene(R"({"meshes": [{"file": "tetra.obj", "name": "a\r\tb\u0001",
                                          "albedo": [-1, 0, 0]}], "cameras": [{}]})",
                          scene_dir());
  });
  EXPECT_CONTAINS(msg, "'a\\r\\tb\\x01'");  // the mesh's name, escaped
  EXPECT_EQ(msg.find('\r'), std::string::npos) << msg;
}

// A header key holding a line break was quoted verbatim by load_npy.
TEST(ErrorsFuzz, NpyHeaderKeyWithLineBreak) {
  const std::string msg =
      error_of([] { penumbra::load_npy(fuzz_input("npy", "regression-newline-in-key.npy")); });
  EXPECT_CONTAINS(msg, "unexpected header key 'fortran\\x0aorder'");
}

// stb_image returned pixels for a PNM header declaring zero rows: a 3x0 image came back.
TEST(ErrorsFuzz, ImageWithoutPixels) {
  EXPECT_FALSE(error_of([] {
                 penumbra::load_image(fuzz_input("image", "regression-pnm-zero-height.pgm"));
               }).empty());
  // The same with a format that is read: a GIF whose screen is 0 pixels wide.
  const std::string path = ::testing::TempDir() + "penumbra_errors_zero.gif";
  std::ofstream(path, std::ios::binary) << std::string(
      "GIF89a\x00\x00\x01\x00\x80\x00\x00\xff\x00\x00\x00\x00\x00"
      ",\x00\x00\x00\x00\x00\x00\x01\x00\x00\x02\x02"
      "D\x01\x00;",
      35);
  const std::string msg = error_of([&] { penumbra::load_image(path); });
  EXPECT_CONTAINS(msg, "cannot read image");
}

// Memory errors of stb_image 2.27 (the version Debian ships), reached through load_image: a JPEG
// Huffman table with more than 256 codes (out-of-bounds write), and a PPM with 16-bit samples
// asked for another channel count (heap-buffer-overflow). Those formats are refused before
// decoding.
TEST(ErrorsFuzz, ImageDecoderMemoryErrorsAreRefused) {
  const std::string jpeg = fuzz_input("image", "regression-jpeg-huffman-overflow.jpg");
  EXPECT_CONTAINS(error_of([&] { penumbra::load_image(jpeg); }), "JPEG files are not read");
  const std::string ppm = fuzz_input("image", "regression-pnm-16bit-overflow.ppm");
  for (int channels : {0, 1, 4})
    EXPECT_CONTAINS(error_of([&] { penumbra::load_image(ppm, channels); }), "PNM");
  // Formats without a signature (stb would have tried TGA) are refused too.
  EXPECT_CONTAINS(error_of([] { penumbra::load_image(fuzz_input("image", "grey_2x2.tga")); }),
                  "unknown image format");
}

// A 35-byte GIF declaring 18177x17993 pixels made stb_image allocate over 2 GiB.
TEST(ErrorsFuzz, ImageHugeDimensionsAreRefusedBeforeDecoding) {
  const std::string msg =
      error_of([] { penumbra::load_image(fuzz_input("image", "regression-gif-huge.gif")); });
  EXPECT_CONTAINS(msg, "18177x17993 pixels is too large");
}

// A PNG chunk declaring 1.6 GB in a 100-byte file made stb_image allocate 2 GiB before reading.
TEST(ErrorsFuzz, ImagePngChunkLongerThanTheFile) {
  const std::string msg =
      error_of([] { penumbra::load_image(fuzz_input("image", "regression-png-huge-chunk.png")); });
  EXPECT_CONTAINS(msg, "corrupt PNG: chunk 'IDAT' declares 1644150802 bytes");
}

// stb_image's message for an unknown PNG chunk quotes the chunk's name, here with a '\r'.
TEST(ErrorsFuzz, ImageDecoderMessageStaysOnOneLine) {
  const std::string msg =
      error_of([] { penumbra::load_image(fuzz_input("image", "regression-png-chunk-name.png")); });
  EXPECT_CONTAINS(msg, "PNG chunk not known");
  EXPECT_EQ(msg.find('\r'), std::string::npos) << msg;
}

// The formats that are read still load, with every channel count; among them a PNG whose first
// IDAT chunk is empty (stb_image would copy it with memcpy(NULL, src, 0), undefined behaviour
// that UBSan reported in the fuzz build; load_image drops empty IDAT chunks).
TEST(ErrorsFuzz, ImageSeedsOfReadFormatsLoad) {
  for (const char* name :
       {"grey_1x1.png", "rgb_2x2.png", "rgba_2x1.png", "grey16_2x2.png", "palette_3x1.png",
        "rgb_2x2.bmp", "rgb_1x1.gif", "flat_2x1.hdr", "regression-png-empty-idat.png"}) {
    SCOPED_TRACE(name);
    for (int channels = 0; channels <= 4; ++channels) {
      const Image im = penumbra::load_image(fuzz_input("image", name), channels);
      EXPECT_GT(im.width, 0);
      EXPECT_GT(im.height, 0);
      if (channels) {
        EXPECT_EQ(im.channels, channels);
      }
      EXPECT_EQ(im.data.size(), size_t(im.width) * im.height * im.channels);
    }
  }
}

}  // namespace
