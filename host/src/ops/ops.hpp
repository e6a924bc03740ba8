#pragma once
// The pipeline stages on the host side, one file each, mirroring kernels/:
// transform.cpp ↔ transform.cl, bin.cpp ↔ bin.cl, raster.cpp ↔ raster.cl.
#include <CL/opencl.hpp>
#include <map>
#include <string>

#include "cl/device.hpp"
#include "penumbra/renderer.hpp"

namespace penumbra::detail {

// Kernel objects of one precision and tuning, built on first use. This is the one place that
// decides the -D options of every program.
class Kernels {
 public:
  Kernels(Context& ctx, Precision precision, RasterTuning tuning);
  cl::Kernel& get(const std::string& file, const std::string& name);
  Context& ctx() { return ctx_; }
  Precision precision() const { return precision_; }
  const RasterTuning& tuning() const { return tuning_; }

 private:
  std::string options(const std::string& file) const;
  Context& ctx_;
  Precision precision_;
  RasterTuning tuning_;
  std::map<std::string, cl::Kernel> kernels_;
};

// Mesh data of a whole scene on the device (all meshes concatenated).
struct DeviceGeometry {
  int nv = 0, nf = 0;
  cl::Buffer vworld;       // nv × real4
  cl::Buffer faces;        // nf × int4
  cl::Buffer albedo;       // 3·nf × real4, per face corner
  cl::Buffer adj_offsets;  // nv + 1 ints: vertex → (face·3 + corner) list
  cl::Buffer adj;
};

struct Bins {
  int tiles_x = 0, tiles_y = 0;
  size_t total = 0;  // face entries over all tiles
  cl::Buffer offsets, counts, faces;
};

// Per-view device state: parameters, transformed vertices, face setup, bins, outputs.
struct ViewState {
  int W = 0, H = 0;
  cl::Buffer P;                 // per-view parameters (kernels/common/layout.h)
  cl::Buffer vscreen;           // nv × real4
  cl::Buffer fbbox, fnormal;    // nf × int4, nf × real4
  Bins bins;
  cl::Buffer image, aux;        // W·H × real4 each
};

// Per-face-corner gradients written by raster_backward.
struct FaceGrads {
  cl::Buffer screen, world, albedo;  // 3·nf × real4
  cl::Buffer light;                  // nf × (2·nlights + 1) × real4
};

void transform_forward(Kernels& k, const DeviceGeometry& g, ViewState& v);
// dL/d world vertex positions (nv × real4) from the per-corner gradients.
cl::Buffer transform_backward(Kernels& k, const DeviceGeometry& g, const ViewState& v,
                              const FaceGrads& fg);

void bin_faces(Kernels& k, const DeviceGeometry& g, ViewState& v);

void raster_forward(Kernels& k, const DeviceGeometry& g, ViewState& v);
FaceGrads raster_backward(Kernels& k, const DeviceGeometry& g, const ViewState& v,
                          int nlights, const cl::Buffer& gimage, const cl::Buffer& gdepth);

}  // namespace penumbra::detail
