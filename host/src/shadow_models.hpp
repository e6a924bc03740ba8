#pragma once
// The shadow models on the device, one row each: what the renderer (renderer.cpp), its backward
// (backward.cpp), the memory estimate (memory.cpp), the views' parameters (view_params.cpp) and
// the kernel builds (ops/kernels.cpp) ask of a model, so that each dispatches through this table
// alone. What needs no device (its word, defaults, frustum) is its row of shadow_models()
// (scene.hpp). Adding a model: docs/architecture.md.
#include <cstddef>

#include "ops/ops.hpp"

namespace penumbra::detail {

// What sizes a model's own buffers of one light (memory.cpp): bytes of a real, faces, texels of
// its map, and the most fragments of one camera view.
struct ModelMemoryInput {
  size_t real_bytes, faces, texels, camera_fragments;
  bool backward;
  Shadows shadows;
};
// A light's buffers of a model's own: `kept` for the whole call, `call` the largest that one
// lookup call holds (one at a time).
struct ModelBytes {
  size_t kept = 0, call = 0;
};

struct ShadowModelPasses {
  ShadowModel value;
  // The kernel file of its lookups and texel gathers (built with ROW and GATHER_CHUNK, in every
  // sampling variant -DSAMPLING_<WORD>, and also with none where `unsampled_variant`).
  const char* lookup_file;
  bool unsampled_variant;
  // P_SHADOW_MODEL of its camera views (layout.h), and whether a hard shadow's fragments keep
  // their receiver-plane depth gradient (P_RECEIVER_PLANE; a soft shadow's always do).
  double layout_code;
  bool hard_receiver_plane;
  // A map its light pass builds after S for its lookups (the paper model's soft shadows: the
  // penumbra map P) where `light_map_needed` says so (null: never), as the stage `light_map_stage`;
  // its backward to dL/dS (adding dL/dD_L to *gsize), then to the light view's faces.
  bool (*light_map_needed)(const RenderParams& p);
  const char* light_map_stage;
  SoftMap (*light_map)(Kernels& k, const DeviceGeometry& g, const View& lv,
                       const ScreenGeometry& sg, const cl::Buffer& S);
  cl::Buffer (*light_map_backward_texels)(Kernels& k, const DeviceGeometry& g, const View& lv,
                                          const ScreenGeometry& sg, const cl::Buffer& S,
                                          const SoftMap& pm, const cl::Buffer& gP, double* gsize);
  void (*light_map_backward_faces)(Kernels& k, const DeviceGeometry& g, const View& lv,
                                   const ScreenGeometry& sg, const cl::Buffer& S, const SoftMap& pm,
                                   const cl::Buffer& gP, FaceGrads& fg);
  // The shadow terms of every fragment of camera view `v` for light `light` (the scene's `L`),
  // and their backward: completes dL/ds, returns dL/d(the light's maps), adds dL/dD_L to *gsize.
  void (*lookup)(Kernels& k, const RenderParams& p, const Light& L, const View& v, Fragments& f,
                 int light, const LightMaps& m);
  MapGrads (*lookup_backward)(Kernels& k, const RenderParams& p, const Light& L, const View& v,
                              Fragments& f, FragmentGrads& fgr, int light, const LightMaps& m,
                              double* gsize);
  // Its buffers of one light that memory.cpp does not count (the light map, search maps, ...).
  ModelBytes (*memory)(const ModelMemoryInput& in);

  bool builds_light_map(const RenderParams& p) const {
    return light_map_needed != nullptr && light_map_needed(p);
  }
};

// The row of model `m`; throws for a model without one.
const ShadowModelPasses& shadow_model_passes(ShadowModel m);
// The row whose lookup_file is `file`; null for any other kernel file.
const ShadowModelPasses* lookup_file_model(const std::string& file);

}  // namespace penumbra::detail
