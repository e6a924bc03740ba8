"""penumbra for PyTorch: differentiable rendering of tensors.

    import torch, penumbra.torch as pt
    vertices, faces = pt.load_mesh("bunny.ply")                 # (V, 3) float32, (F, 3) int64
    camera = pt.Camera.look_at((0, 1, 4), (0, 0, 0), width=128, height=128)
    light = pt.Light.point(torch.tensor([1.0, 4.0, 1.0]), size=0.3)
    colour, silhouette, depth = pt.render(vertices, faces, camera, light)
    colour.mean().backward()                                     # penumbra's exact backward

render() takes vertices (V, 3), a batch (B, V, 3) of shapes sharing faces, or a list of meshes;
it returns colour (C, H, W, 3), silhouette and depth (C, H, W) for the C cameras, with a leading
B for a batch. It is differentiable in the vertices, albedo, light positions (directions),
colours and sizes, and ambient light. float32 tensors render in float, float64 in double. Each
light's shadow-map frustum, unless given, is fitted to the geometry of the call, and the
derivative treats it as a constant of the call. SceneRenderer renders a penumbra.Scene whose
parameters come from tensors; with torch 2.4 or later its call is the operator
penumbra::scene_render, which torch.compile holds in one graph. Tensors live on the CPU;
penumbra's own device (any OpenCL device) is chosen by the Context. docs/api.md has it all.
"""
import functools
import itertools
import threading
import weakref
from numbers import Real

import numpy as np
import torch

import penumbra

__all__ = ["Camera", "Light", "RenderParams", "render", "load_mesh", "SceneRenderer", "Render"]

Camera = penumbra.Camera
RenderParams = penumbra.RenderParams


class Light:
    """A light whose position (or direction), colour and size may be tensors: render() then
    gives them gradients. `frustum` (a penumbra.LightFrustum) fixes its shadow map's frustum;
    None fits it to the geometry of every call. A point light's `shadow_map` ("auto", "frustum"
    or "cube") says how its shadows are mapped: "auto" takes a cube where one frustum cannot hold
    its casters (a light among the objects)."""

    def __init__(self, type, vector, color=(1.0, 1.0, 1.0), size=0.0, frustum=None,
                 shadow_map="auto"):
        self.type, self.vector, self.color, self.size, self.frustum = type, vector, color, size, frustum
        if isinstance(shadow_map, str):
            if shadow_map not in penumbra.ShadowMapShape.__members__:
                raise penumbra.Error(f"shadow_map '{shadow_map}' is none of "
                                     + ", ".join(penumbra.ShadowMapShape.__members__))
            shadow_map = penumbra.ShadowMapShape.__members__[shadow_map]
        self.shadow_map = shadow_map

    @classmethod
    def point(cls, position, *, color=(1.0, 1.0, 1.0), size=0.0, frustum=None,
              shadow_map="auto"):
        """A point light at `position`: a sphere of diameter `size` for soft shadows."""
        return cls(penumbra.LightType.point, position, color, size, frustum, shadow_map)

    @classmethod
    def directional(cls, direction, *, color=(1.0, 1.0, 1.0), size=0.0, frustum=None):
        """A directional light travelling along `direction`."""
        return cls(penumbra.LightType.directional, direction, color, size, frustum)

    def _numbers(self):
        """The parameters row as a tuple of 7 numbers where all are plain numbers, else ()."""
        try:
            flat = (*self.vector, *self.color, self.size)
        except TypeError:  # not sequences: checked and named by row()
            return ()
        plain = len(flat) == 7 and all(isinstance(v, Real) for v in flat)
        return tuple(map(float, flat)) if plain else ()

    def row(self, dtype):
        """The light as its parameters row (7,): vector, colour, size."""
        parts = [_real(x, name, dtype).reshape(-1) for x, name in
                 ((self.vector, "a light's position or direction"), (self.color, "a light's colour"),
                  (self.size, "a light's size"))]
        if [p.numel() for p in parts] != [3, 3, 1]:
            raise penumbra.Error("a light needs a 3-vector position or direction, a 3-vector "
                                 "colour and one size")
        return torch.cat(parts)

    def template(self):
        """A penumbra.Light of this type and frustum (its values come from row())."""
        light = penumbra.Light(type=self.type, shadow_map=self.shadow_map)
        if self.frustum is not None:
            light.frustum = self.frustum
        return light


def load_mesh(path, dtype=torch.float32, refuse_degenerate=False):
    """A mesh file (.obj, .ply, .stl, .gltf, .glb, .off) as tensors: vertices (V, 3) of `dtype`,
    faces (F, 3) int64. Zero-area faces are dropped with a warning, or refused."""
    mesh = penumbra.load_mesh(str(path), refuse_degenerate=refuse_degenerate)
    return (torch.from_numpy(np.array(mesh.vertices)).to(dtype),
            torch.from_numpy(np.array(mesh.faces)).long())


class _Source:
    """What a call renders besides its parameters: a template scene whose meshes give the faces,
    and the cameras, lights and settings (a tuple, as `setup` below gives them)."""

    def __init__(self, template, setup):
        self.template, self.setup = template, setup

    @classmethod
    def of(cls, scene):
        """`scene` itself if a _Source, else a copy of the penumbra.Scene as one."""
        if isinstance(scene, cls):
            return scene
        return cls(penumbra.Scene(scene), (scene.cameras, scene.lights, scene.params))


class _Shape:
    """One shape of a call: its source and its parameters as arrays laid out as
    Scene.parameters()."""

    def __init__(self, source, arrays):
        self.source, self.arrays = source, arrays


class _Slot:
    """A Renderer, its own copy of the template scene it renders (made again only when the
    faces change, so that a call copies no faces), and the shape it rendered last, for one
    element of a batch: backward differentiates the most recent render, so it renders its own
    shape again first when another render came in between (from torch running several
    forwards, or another thread)."""

    def __init__(self, context, precision):
        self.renderer = penumbra.Renderer(context, precision)
        self.lock = threading.Lock()
        self.last = self.template = self.scene = None

    def _load(self, shape):
        self.last = None  # until the shape's render has succeeded
        template = shape.source.template
        if self.template is not template:
            self.scene, self.template = penumbra.Scene(template), template
        self.scene.cameras, self.scene.lights, self.scene.params = shape.source.setup
        self.scene.set_parameters(*shape.arrays)

    def render_into(self, shape, colour, silhouette, depth):
        with self.lock:
            self._load(shape)
            self.renderer.render_into(self.scene, colour, silhouette, depth)
            self.last = shape

    def backward(self, shape, colour, silhouette, depth):
        with self.lock:
            if self.last is not shape:
                self._load(shape)
                self.renderer.render(self.scene)
                self.last = shape
            return self.renderer.backward_parameters(self.scene, colour, silhouette, depth)


class _Slots:
    """The slots of one context and precision, made as batches need them."""

    def __init__(self, context):
        self.context, self.lock, self.slots = context, threading.Lock(), {}

    def get(self, precision, count):
        with self.lock:
            slots = self.slots.setdefault(precision, [])
            while len(slots) < count:
                slots.append(_Slot(self.context, precision))
            return slots[:count]


_default = {}
_default_lock = threading.Lock()


def _default_slots(context):
    """The slots of `context`, or of a Context on the default device made once."""
    with _default_lock:
        if context is None:
            if "context" not in _default:
                _default["context"] = penumbra.Context()
            context = _default["context"]
        key = id(context)
        if key not in _default:
            _default[key] = (context, _Slots(context))
        return _default[key][1]


def _precision(dtype):
    if dtype == torch.float64:
        return penumbra.Precision.double
    if dtype == torch.float32:
        return penumbra.Precision.float
    raise penumbra.Error(f"vertices must be float32 or float64, not {str(dtype)[6:]}")


def _real(x, name, dtype):
    """`x` as a tensor of `dtype`: a tensor must be float32 or float64, the rest is converted
    (a sequence holding tensors joined, keeping their gradients)."""
    if isinstance(x, (list, tuple)) and any(isinstance(e, torch.Tensor) for e in x):
        return torch.cat([_real(e, name, dtype).reshape(-1) for e in x])
    if not isinstance(x, torch.Tensor):
        return torch.as_tensor(x, dtype=dtype)
    if x.dtype not in (torch.float32, torch.float64):
        raise penumbra.Error(f"{name} must be float32 or float64, not {str(x.dtype)[6:]}")
    return x.to(dtype)


def _array(t):
    """A tensor's values as a NumPy array, without a copy (the module reads any strides)."""
    return t.detach().numpy() if t.requires_grad else t.numpy()


@functools.lru_cache(maxsize=64)
def _tensor_of(numbers, dtype):
    """torch.tensor(numbers), made once per value: torch calls cost tens of µs after a render."""
    return torch.tensor(numbers, dtype=dtype)


def _shapes(source, vertices, albedo, lights, ambient):
    """The shapes of a batch: `source`'s, their parameters from the tensors (each converted
    once for the whole batch: torch calls cost per call)."""
    v, a, shared = _array(vertices), _array(albedo), (_array(lights), _array(ambient))
    return [_Shape(source, (v[b], a[b] if a.ndim == 3 else a, *shared)) for b in range(len(v))]


def _output_size(cameras, batch):
    """(B, C, H, W) of a render of `cameras`, which must share one image size."""
    if len({(c.width, c.height) for c in cameras}) != 1:
        raise penumbra.Error("every camera must have the same image size (got "
                             f"{sorted({(c.width, c.height) for c in cameras})})")
    return (batch, len(cameras), cameras[0].height, cameras[0].width)


def _render(slots, shapes, dtype, batched=True):
    """colour (B, C, H, W, 3), silhouette and depth (B, C, H, W) of `shapes`, one per slot."""
    size = _output_size(shapes[0].source.setup[0], len(shapes))
    real = np.float32 if dtype == torch.float32 else np.float64
    out = np.empty(size + (3,), real), np.empty(size, real), np.empty(size, real)
    for b, s in enumerate(shapes):  # (NumPy's views: fewer torch calls, which cost per call)
        slots[b].render_into(s, *(o[b] for o in out))
    return tuple(torch.from_numpy(o if batched else o[0]) for o in out)


def _backward(slots, shapes, batched_albedo, dtypes, d_outputs, batched=True):
    """(d vertices, d albedo, d lights, d ambient) of the renders of `shapes` from the
    gradients of their outputs (each read once for the whole batch)."""
    d = [_array(g) if batched else _array(g)[None] for g in d_outputs]
    grads = [slots[b].backward(s, *(g[b] for g in d)) for b, s in enumerate(shapes)]
    stack = lambda key: torch.from_numpy(  # noqa: E731 (one shape's: a view, not a copy)
        grads[0][key][None] if len(grads) == 1 else np.stack([g[key] for g in grads]))
    d_albedo = stack("albedo") if batched_albedo else stack("albedo").sum(0)
    out = [stack("vertices"), d_albedo, stack("lights").sum(0), stack("ambient").sum(0)]
    return tuple(g.to(t) for g, t in zip(out, dtypes))


class Render(torch.autograd.Function):
    """(scene, slots, vertices (B, V, 3), albedo ((B,) A, 3), lights (L, 7), ambient (3,)
    [, batched]) -> colour (B, C, H, W, 3), silhouette and depth (B, C, H, W) (batched False:
    B = 1, left out): scene's cameras, faces and settings, with its parameters from the tensors
    (laid out as Scene.parameters())."""

    @staticmethod
    def forward(ctx, scene, slots, vertices, albedo, lights, ambient, batched=True):
        shapes = _shapes(_Source.of(scene), vertices, albedo, lights, ambient)
        out = _render(slots, shapes, vertices.dtype, batched)
        ctx.slots, ctx.shapes, ctx.batched_albedo = slots, shapes, albedo.dim() == 3
        ctx.batched = batched
        ctx.dtypes = [t.dtype for t in (vertices, albedo, lights, ambient)]
        # The shapes' arrays share the tensors' memory: saved, torch refuses a backward after
        # one of them was changed in place.
        ctx.save_for_backward(vertices, albedo, lights, ambient)
        return out

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, d_colour, d_silhouette, d_depth):
        ctx.saved_tensors  # noqa: B018 (torch's check of in-place changes)
        return (None, None, *_backward(ctx.slots, ctx.shapes, ctx.batched_albedo, ctx.dtypes,
                                       (d_colour, d_silhouette, d_depth), ctx.batched), None)


def _meshes(vertices, faces):
    """(vertices (B, V, 3), faces per mesh, vertex count per mesh, batched)."""
    if isinstance(vertices, (list, tuple)):
        if not isinstance(faces, (list, tuple)) or len(faces) != len(vertices):
            raise penumbra.Error("a list of meshes needs a list of as many face tensors")
        counts = [v.shape[-2] for v in vertices]
        vertices = torch.cat(list(vertices), dim=-2)
    else:
        counts, faces = [vertices.shape[-2]], [faces]
    if not isinstance(vertices, torch.Tensor) or vertices.dim() not in (2, 3) or vertices.shape[-1] != 3:
        raise penumbra.Error(f"vertices must be a (V, 3) or (B, V, 3) tensor, not "
                             f"{tuple(getattr(vertices, 'shape', ())) or type(vertices).__name__}")
    batched = vertices.dim() == 3
    return (vertices if batched else vertices.unsqueeze(0)), faces, counts, batched


def _albedo(albedo, vertices):
    """Albedo rows per vertex: (A, 3) or (B, A, 3); None is 0.8 grey, a (3,) is every vertex's."""
    if albedo is None:  # (one row seen as V: no array of V rows to make and read)
        return _tensor_of((0.8,) * 3, vertices.dtype).expand(vertices.shape[1], 3)
    if isinstance(albedo, (list, tuple)) and isinstance(albedo[0], torch.Tensor):
        albedo = torch.cat([_real(a, "albedo", vertices.dtype) for a in albedo], dim=-2)
    albedo = _real(albedo, "albedo", vertices.dtype)
    if albedo.shape == (3,):
        return albedo.expand(vertices.shape[1], 3)
    return albedo


def _as_list(x):
    return list(x) if isinstance(x, (list, tuple)) else [x]


_templates = {}  # (id, version) of each face tensor, vertex counts -> (weak references, Scene)
_templates_lock = threading.Lock()
_TEMPLATES_KEPT = 4


def _template(faces, counts):
    """A scene of meshes with these faces (their vertices 0), made once for face tensors that
    are the same objects, unchanged since (their versions count changes in place): a call then
    neither converts nor copies its faces. The tensors are referenced weakly: one that is gone
    matches nothing, so no later tensor that takes its id can match."""
    faces = [f if isinstance(f, torch.Tensor) else torch.as_tensor(f) for f in faces]
    key = (tuple((id(f), f._version) for f in faces), tuple(counts))
    with _templates_lock:
        hit = _templates.get(key)
    if hit is not None and all(ref() is f for ref, f in zip(hit[0], faces)):
        return hit[1]
    scene = penumbra.Scene()
    scene.meshes = [penumbra.Mesh(vertices=np.zeros((n, 3)), faces=_array(f))
                    for n, f in zip(counts, faces)]
    with _templates_lock:
        _templates.pop(key, None)
        while len(_templates) >= _TEMPLATES_KEPT:
            _templates.pop(next(iter(_templates)))
        _templates[key] = ([weakref.ref(f) for f in faces], scene)
    return scene


def _source(faces, counts, cameras, lights, params):
    setup = penumbra.Scene()  # checks and copies the cameras, lights and settings
    setup.cameras, setup.lights, setup.params = cameras, [l.template() for l in lights], params
    return _Source(_template(faces, counts), (setup.cameras, setup.lights, setup.params))


def render(vertices, faces, cameras, lights, *, albedo=None, ambient=0.2, params=None,
           context=None):
    """Renders meshes from tensors; differentiable. Returns (colour, silhouette, depth).

    vertices: (V, 3) float32 or float64, (B, V, 3) for B shapes sharing `faces`, or a list of
    meshes' vertices (with a list of their faces). faces: (F, 3) integers. cameras: one
    penumbra.Camera (Camera.look_at) or a list, of one image size. lights: Light.point /
    Light.directional (or penumbra.Light), one or a list; [] for ambient light alone. albedo:
    None (0.8 grey), (3,), or per vertex (V, 3) or (B, V, 3). ambient: a number or (3,).
    params: a penumbra.RenderParams (None: the defaults with hard shadows). context: a
    penumbra.Context (None: the default device, made once).
    """
    vertices, faces, counts, batched = _meshes(vertices, faces)
    dtype = vertices.dtype
    precision = _precision(dtype)
    lights = [l if isinstance(l, Light) else _torch_light(l) for l in _as_list(lights)]
    if params is None:
        params = penumbra.RenderParams()
        params.shadows = penumbra.Shadows.hard
    source = _source(faces, counts, _as_list(cameras), lights, params)
    rows = _light_rows(lights, dtype)
    if isinstance(ambient, Real):
        ambient = _tensor_of((float(ambient),) * 3, dtype)
    ambient = _real(ambient, "ambient", dtype).expand(3)
    slots = _default_slots(context).get(precision, vertices.shape[0])
    return Render.apply(source, slots, vertices, _albedo(albedo, vertices), rows, ambient, batched)


def _light_rows(lights, dtype):
    """The lights' rows (L, 7); made once for lights given as numbers alone."""
    numbers = tuple(light._numbers() for light in lights)
    if lights and all(numbers):
        return _tensor_of(numbers, dtype)
    return torch.stack([l.row(dtype) for l in lights]) if lights else torch.zeros((0, 7), dtype=dtype)


def _torch_light(light):
    if not isinstance(light, penumbra.Light):
        raise penumbra.Error(f"lights must be penumbra.torch.Light or penumbra.Light, not "
                             f"{type(light).__name__}")
    vector = light.direction if light.type == penumbra.LightType.directional else light.position
    return Light(light.type, vector, light.color, light.size,
                 light.frustum if light.frustum.fitted else None)


class SceneRenderer:
    """Renders one scene whose parameters come from tensors (laid out as Scene.parameters()).

    The scene is copied; the shadow-map frustum of every light that is not given is fitted
    once, here, to the scene as it is, and then stays fixed (as in the tool and its gradient
    check), so that the rendered function of the parameters is the one whose derivative
    backward computes. A render whose casters leave a fixed frustum prints one warning line.
    """

    def __init__(self, scene, context=None, device=""):
        self._scene = penumbra.Scene(scene)
        penumbra.refit_light_frusta(self._scene)
        self._source = _Source.of(self._scene)
        self.context = context if context is not None else penumbra.Context(device)
        self._slots = _Slots(self.context)
        self._lock, self._last = threading.Lock(), None
        self._key = f"scene_renderer_{next(_keys)}"
        _registered[self._key] = self

    @property
    def scene(self):
        """A copy of the scene it renders (changing the copy changes nothing here)."""
        return penumbra.Scene(self._scene)

    def parameters(self, dtype=torch.float64):
        """The scene's parameters as tensors: a dict of vertices, albedo, lights, ambient."""
        return {k: torch.from_numpy(v).to(dtype) for k, v in self._scene.parameters().items()}

    def __call__(self, vertices, albedo, lights, ambient):
        """(colour (C, H, W, 3), silhouette (C, H, W), depth (C, H, W)); differentiable."""
        if _operator is not None:
            return tuple(o[0] for o in _operator(self._key, vertices[None], albedo, lights, ambient))
        slots = self._slots.get(_precision(vertices.dtype), 1)
        return Render.apply(self._source, slots, vertices[None], albedo, lights, ambient, False)

    def _render(self, vertices, albedo, lights, ambient):
        """The operator's forward: the render, and its scenes kept for the backward."""
        slots = self._slots.get(_precision(vertices.dtype), vertices.shape[0])
        inputs = [t.detach().clone() for t in (vertices, albedo, lights, ambient)]
        shapes = _shapes(self._source, *inputs)
        out = _render(slots, shapes, vertices.dtype)
        with self._lock:
            self._last = (inputs, shapes)
        return out

    def _backward(self, inputs, d_outputs):
        """The operator's backward: the shapes of the last render where its inputs were these
        (the slots' renders of them stand), else new ones (which the slots render again)."""
        with self._lock:
            last = self._last
        if last is not None and all(torch.equal(a, b) for a, b in zip(last[0], inputs)):
            shapes = last[1]
        else:
            shapes = _shapes(self._source, *[t.detach().clone() for t in inputs])
        vertices, albedo = inputs[0], inputs[1]
        slots = self._slots.get(_precision(vertices.dtype), vertices.shape[0])
        return _backward(slots, shapes, albedo.dim() == 3, [t.dtype for t in inputs], d_outputs)


# torch.compile: where torch has torch.library.custom_op (2.4 and later), a SceneRenderer's call
# is the operator penumbra::scene_render (tensors and the renderer's key in, tensors out), with
# its backward penumbra::scene_render_backward, so that a compiled graph holds it whole.
_registered = weakref.WeakValueDictionary()  # key -> SceneRenderer
_keys = itertools.count()


def _register_operator():
    from typing import Tuple
    Tensor = torch.Tensor

    @torch.library.custom_op("penumbra::scene_render", mutates_args=())
    def scene_render(key: str, vertices: Tensor, albedo: Tensor, lights: Tensor,
                     ambient: Tensor) -> Tuple[Tensor, Tensor, Tensor]:
        return _registered[key]._render(vertices, albedo, lights, ambient)

    @torch.library.custom_op("penumbra::scene_render_backward", mutates_args=())
    def scene_render_backward(key: str, vertices: Tensor, albedo: Tensor, lights: Tensor,
                              ambient: Tensor, d_colour: Tensor, d_silhouette: Tensor,
                              d_depth: Tensor) -> Tuple[Tensor, Tensor, Tensor, Tensor]:
        return _registered[key]._backward((vertices, albedo, lights, ambient),
                                          (d_colour, d_silhouette, d_depth))

    @scene_render.register_fake
    def _(key, vertices, albedo, lights, ambient):
        size = _output_size(_registered[key]._scene.cameras, vertices.shape[0])
        return vertices.new_empty(size + (3,)), vertices.new_empty(size), vertices.new_empty(size)

    @scene_render_backward.register_fake
    def _(key, vertices, albedo, lights, ambient, d_colour, d_silhouette, d_depth):
        return tuple(torch.empty_like(t) for t in (vertices, albedo, lights, ambient))

    def setup_context(ctx, inputs, output):
        ctx.key = inputs[0]
        ctx.save_for_backward(*inputs[1:])

    def backward(ctx, d_colour, d_silhouette, d_depth):
        vertices = ctx.saved_tensors[0]
        size = _output_size(_registered[ctx.key]._scene.cameras, vertices.shape[0])
        d = [torch.zeros(size + extra, dtype=vertices.dtype) if g is None else g  # unused outputs
             for g, extra in zip((d_colour, d_silhouette, d_depth), ((3,), (), ()))]
        return (None, *scene_render_backward(ctx.key, *ctx.saved_tensors, *d))

    scene_render.register_autograd(backward, setup_context=setup_context)
    return torch.ops.penumbra.scene_render


_operator = _register_operator() if hasattr(torch.library, "custom_op") else None
