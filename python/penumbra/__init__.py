"""penumbra: a differentiable soft rasterizer with hard and soft shadows, on OpenCL.

The C++ library for Python: scenes, devices, and a Renderer whose render() gives colour,
silhouette and depth per camera as NumPy arrays and whose backward() gives the gradients of a
loss with respect to vertices, albedo, lights and ambient light. penumbra.torch renders
tensors differentiably (penumbra.torch.render). Errors raise penumbra.Error with the library's
one-line message (the same one the penumbra tool prints). docs/api.md documents it all.
"""
from ._penumbra import *  # noqa: F401,F403  every class and function of the C++ module
from ._penumbra import __version__, Scene, load_scene

__all__ = [name for name in dir() if not name.startswith("_")] + ["data_dir", "bundled_scene"]


def data_dir():
    """The bundled data installed with the module (a pathlib.Path): scenes/turnaround.json and
    meshes/."""
    from pathlib import Path
    return Path(__file__).resolve().parent / "data"


def bundled_scene() -> Scene:
    """The bundled scene: a unit sphere on a ground plane, one point light, hard shadows."""
    return load_scene(str(data_dir() / "scenes" / "turnaround.json"))
