// The Renderer for Python (module.cpp binds the rest): calls with the GIL released, Ctrl-C
// between stages, outputs moved out or written into the caller's arrays.
#include <nanobind/nanobind.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <string>
#include <vector>

#include "arrays.hpp"
#include "penumbra/context.hpp"
#include "penumbra/error.hpp"
#include "penumbra/renderer.hpp"
#include "penumbra/scene.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace penumbra;

namespace penumbra::python {

namespace {

// Ctrl-C during a render: the renderer checks at every stage, and a pending KeyboardInterrupt
// abandons the call (Renderer::set_interrupt_check).
void check_signals() {
  nb::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() != 0) throw nb::python_error();
}

// Runs a renderer call with the GIL released (other threads run meanwhile).
template <class Call>
auto released(Call&& call) {
  nb::gil_scoped_release unlocked;
  return call();
}

nb::list views_out(std::vector<RenderOutput>&& views) {
  nb::list out;
  for (RenderOutput& v : views) {
    nb::dict d;
    d["color"] = image_out(std::move(v.color));
    d["silhouette"] = image_out(std::move(v.silhouette));
    d["depth"] = image_out(std::move(v.depth));
    out.append(d);
  }
  return out;
}

std::vector<OutputGrads> grads_from_dicts(const nb::list& grads) {
  std::vector<OutputGrads> dL(nb::len(grads));
  for (size_t i = 0; i < dL.size(); ++i) {
    nb::handle g = grads[i];
    if (g.is_none()) continue;
    const std::string camera = "camera " + std::to_string(i);
    if (!nb::isinstance<nb::dict>(g))
      throw Error("the gradients of " + camera + " must be a dict or None");
    for (auto [key, value] : nb::borrow<nb::dict>(g)) {
      std::string name = nb::cast<std::string>(nb::str(key));
      Image* image = name == "color"        ? &dL[i].color
                     : name == "silhouette" ? &dL[i].silhouette
                     : name == "depth"      ? &dL[i].depth
                                            : nullptr;
      if (image == nullptr)
        throw Error("unknown output '" + name + "' in the gradients (color, silhouette, depth)");
      if (!value.is_none()) *image = image_in(value, name.append(" of ").append(camera));
    }
  }
  return dL;
}

nb::dict scene_grads_out(SceneGrads&& g) {
  nb::dict out;
  nb::list vertices, albedo;
  for (auto& v : g.vertices) vertices.append(rows_out<double>(std::move(v)));
  for (auto& a : g.albedo) albedo.append(rows_out<double>(std::move(a)));
  out["vertices"] = vertices;
  out["albedo"] = albedo;
  out["light_position"] = rows_out<double>(std::move(g.light_position));
  out["light_color"] = rows_out<double>(std::move(g.light_color));
  const size_t lights = g.light_size.size();
  out["light_size"] = adopt<const double>(std::move(g.light_size), {lights});
  out["ambient"] =
      adopt<const double>(std::vector<double>{g.ambient.x, g.ambient.y, g.ambient.z}, {3});
  return out;
}

void bind_maps(nb::class_<Renderer>& r) {
  const auto maps = [](std::vector<Image>&& images) {
    nb::list out;
    for (Image& s : images) out.append(image_out(std::move(s)));
    return out;
  };
  r.def(
       "shadow_maps",
       [maps](const Renderer& self) { return maps(released([&] { return self.shadow_maps(); })); },
       "The shadow map of every light from the most recent render with shadows on.")
      .def(
          "penumbra_maps",
          [maps](const Renderer& self) {
            return maps(released([&] { return self.penumbra_maps(); }));
          },
          "The penumbra map of every light from the most recent render with soft shadows.")
      .def(
          "fragment_counts",
          [](const Renderer& self) { return released([&] { return self.fragment_counts(); }); },
          "How many fragments each camera's view kept in the most recent render (empty before "
          "one): the (pixel, face) pairs whose aggregation weight is at least weight_eps times "
          "the pixel's largest.");
}

}  // namespace

void bind_renderer(nb::module_& m) {
  nb::class_<Renderer> r(m, "Renderer");
  r.def(
       "__init__",
       [](Renderer* self, Context& context, Precision precision) {
         new (self) Renderer(context, precision);
         self->set_interrupt_check(check_signals);
       },
       "context"_a, "precision"_a = Precision::Float, nb::keep_alive<1, 2>(),
       "A renderer on the context's device. Threads may share it: its calls run one at a time.")
      .def_prop_ro("precision", &Renderer::precision)
      .def(
          "render",
          [](Renderer& self, const Scene& s) {
            return views_out(released([&] { return self.render(s); }));
          },
          "scene"_a,
          "Renders every camera: a list of dicts with color (H, W, 3), silhouette (H, W) and "
          "depth (H, W), float64 arrays.")
      .def(
          "render_into",
          [](Renderer& self, const Scene& s, const OutArray& colour, const OutArray& silhouette,
             const OutArray& depth) {
            const OutputArrays out = output_arrays(s, colour, silhouette, depth);
            released([&] {
              if (out.single)
                self.render_into(s, out.f32);
              else
                self.render_into(s, out.f64);
            });
          },
          "scene"_a, "colour"_a, "silhouette"_a, "depth"_a,
          "Renders every camera into (C, H, W, 3) and (C, H, W) float32 or float64 arrays.")
      .def(
          "backward",
          [](Renderer& self, const Scene& s, const nb::list& grads) {
            std::vector<OutputGrads> dL = grads_from_dicts(grads);
            return scene_grads_out(released([&] { return self.backward(s, dL); }));
          },
          "scene"_a, "grads"_a,
          "Gradients of a loss given dL/d(outputs) per camera (dicts like render's; a missing "
          "key or None is zero), by the derivative of the most recent render of this scene: a "
          "dict of vertices and albedo (lists of (N, 3) per mesh), light_position, light_color "
          "(L, 3), light_size (L,) and ambient (3,).")
      .def(
          "backward_parameters",
          [](Renderer& self, const Scene& s, nb::handle colour, nb::handle silhouette,
             nb::handle depth) {
            const GradArrays g = grad_arrays(s, colour, silhouette, depth);
            SceneGrads grads = released(
                [&] { return g.single ? self.backward(s, g.f32) : self.backward(s, g.f64); });
            return g.float32 ? parameter_grads<float>(std::move(grads))
                             : parameter_grads<double>(std::move(grads));
          },
          "scene"_a, "colour"_a.none(), "silhouette"_a.none(), "depth"_a.none(),
          "backward() given (C, H, W, 3) and (C, H, W) gradient arrays (None: zero), its "
          "gradients laid out as Scene.parameters(): float32 arrays where every array given is "
          "float32, else float64.");
  bind_maps(r);
}

}  // namespace penumbra::python
