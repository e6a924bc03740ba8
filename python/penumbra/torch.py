"""penumbra for PyTorch: rendering as a torch.autograd.Function.

    import penumbra, penumbra.torch
    scene = penumbra.bundled_scene()
    render = penumbra.torch.SceneRenderer(scene)
    p = render.parameters(dtype=torch.float64)     # vertices, albedo, lights, ambient
    colour, silhouette, depth = render(p["vertices"].requires_grad_(), p["albedo"], ...)
    loss.backward()                                # calls penumbra's backward

The parameters are laid out as Scene.parameters(): vertices (V, 3) and albedo (A, 3) with the
rows of every mesh in turn, lights (L, 7) (position, or direction for a directional light,
colour, size D_L: the tool's lights.npy), ambient (3,). The outputs stack every camera: colour (C, H, W, 3), silhouette and
depth (C, H, W). float64 inputs render in double precision, float32 ones in float (the tool's
default); the outputs have the inputs' dtype. Tensors live on the CPU; penumbra's own device
(any OpenCL device) is chosen by the Context.
"""
import numpy as np
import torch

import penumbra

__all__ = ["Render", "SceneRenderer", "render"]


class SceneRenderer:
    """Renders one scene whose geometry and lights come from tensors.

    The scene is copied; the shadow-map frustum of every light that is not given is fitted
    once, here, to the scene and its shadow settings as they are, and then stays fixed (as in
    the tool and its gradient check), so that the rendered function of the parameters is the
    one whose derivative backward computes.
    """

    def __init__(self, scene, context=None, device=""):
        self.scene = penumbra.Scene(scene)
        penumbra.refit_light_frusta(self.scene)
        self.context = context if context is not None else penumbra.Context(device)
        self._renderers = {}
        self._last = {}  # precision -> the scene its renderer rendered last

    def parameters(self, dtype=torch.float64):
        """The scene's parameters as tensors: a dict of vertices, albedo, lights, ambient."""
        return {k: torch.from_numpy(v).to(dtype) for k, v in self.scene.parameters().items()}

    def __call__(self, vertices, albedo, lights, ambient):
        return Render.apply(vertices, albedo, lights, ambient, self)

    def _renderer(self, precision):
        if precision not in self._renderers:
            self._renderers[precision] = penumbra.Renderer(self.context, precision)
        return self._renderers[precision]

    def render(self, scene, precision):
        views = self._renderer(precision).render(scene)
        self._last[precision] = scene
        return views

    def backward(self, scene, precision, grads):
        # The renderer's backward differentiates its most recent render: render this scene
        # again if another render came in between (torch may run several forwards first).
        if self._last.get(precision) is not scene:
            self.render(scene, precision)
        return self._renderer(precision).backward(scene, grads)


def _stack(arrays, name):
    if len({a.shape for a in arrays}) != 1:
        raise penumbra.Error(f"penumbra.torch needs every camera to have the same image size "
                             f"({name} sizes {sorted({a.shape[:2] for a in arrays})})")
    # One camera: a view of the array that C++ handed over, no copy.
    return arrays[0][None] if len(arrays) == 1 else np.stack(arrays)


def _numpy(t):
    return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=np.float64)


class Render(torch.autograd.Function):
    """(vertices, albedo, lights, ambient, SceneRenderer) -> (colour, silhouette, depth)."""

    @staticmethod
    def forward(ctx, vertices, albedo, lights, ambient, renderer):
        dtype = vertices.dtype
        if dtype not in (torch.float32, torch.float64):
            raise penumbra.Error(f"vertices must be float32 or float64, not {dtype}")
        precision = penumbra.Precision.double if dtype == torch.float64 else penumbra.Precision.float
        scene = penumbra.Scene(renderer.scene)
        scene.set_parameters(_numpy(vertices), _numpy(albedo), _numpy(lights), _numpy(ambient))
        views = renderer.render(scene, precision)
        ctx.renderer, ctx.scene, ctx.precision = renderer, scene, precision
        ctx.dtypes = [t.dtype for t in (vertices, albedo, lights, ambient)]
        out = [torch.from_numpy(_stack([v[k] for v in views], k)).to(dtype)
               for k in ("color", "silhouette", "depth")]
        return tuple(out)

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, d_colour, d_silhouette, d_depth):
        dc, ds, dd = (_numpy(g) for g in (d_colour, d_silhouette, d_depth))
        grads = [{"color": dc[i], "silhouette": ds[i], "depth": dd[i]} for i in range(len(dc))]
        g = ctx.renderer.backward(ctx.scene, ctx.precision, grads)
        d_vertices = np.concatenate(g["vertices"]) if g["vertices"] else np.zeros((0, 3))
        d_albedo = np.concatenate(g["albedo"]) if g["albedo"] else np.zeros((0, 3))
        d_lights = np.concatenate([g["light_position"], g["light_color"],
                                   g["light_size"][:, None]], axis=1)
        out = [torch.from_numpy(a).to(t)
               for a, t in zip((d_vertices, d_albedo, d_lights, g["ambient"]), ctx.dtypes)]
        return (*out, None)


def render(renderer, vertices, albedo, lights, ambient):
    """Renders renderer.scene (a SceneRenderer) with the given parameters; differentiable."""
    return Render.apply(vertices, albedo, lights, ambient, renderer)
