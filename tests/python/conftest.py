"""Shared fixtures of the Python tests: a small scene built in code, the penumbra tool."""
import atexit
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

import penumbra

ROOT = Path(__file__).resolve().parents[2]

# Compiled kernels go to a folder of this test run, never to the user's kernel cache (README,
# "The kernel cache"); the tool run by the tests inherits it. A cache given by the caller wins.
if "PENUMBRA_CACHE_DIR" not in os.environ:
    os.environ["PENUMBRA_CACHE_DIR"] = tempfile.mkdtemp(prefix="penumbra_kernel_cache_")
    atexit.register(shutil.rmtree, os.environ["PENUMBRA_CACHE_DIR"], ignore_errors=True)


def small_scene(shadows="none", size=10):
    """An octahedron above a ground quad, one point light, one camera of size x size pixels."""
    ball = penumbra.Mesh()
    ball.name = "ball"
    ball.vertices = np.array([[0.5, 0.9, 0], [-0.5, 0.9, 0], [0, 1.4, 0], [0, 0.4, 0],
                              [0, 0.9, 0.5], [0, 0.9, -0.5]], dtype=np.float64)
    ball.faces = np.array([[0, 2, 4], [4, 2, 1], [1, 2, 5], [5, 2, 0], [4, 3, 0], [1, 3, 4],
                           [5, 3, 1], [0, 3, 5]], dtype=np.int32)
    ball.albedo = np.linspace(0.3, 0.9, 18).reshape(6, 3)
    ground = penumbra.Mesh()
    ground.name = "ground"
    ground.vertices = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]], dtype=np.float64)
    ground.faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)
    ground.albedo = np.full((4, 3), 0.8)
    camera = penumbra.Camera()
    camera.eye, camera.target = (0.3, 2.5, 3.0), (0, 0.6, 0)
    camera.near, camera.far = 0.5, 10.0
    camera.width = camera.height = size
    light = penumbra.Light()
    light.position, light.color, light.size = (1.0, 4.0, 1.0), (0.9, 0.8, 0.7), 0.6
    scene = penumbra.Scene()
    scene.meshes, scene.cameras, scene.lights = [ball, ground], [camera], [light]
    scene.ambient = (0.2, 0.25, 0.3)
    p = scene.params
    p.sigma, p.gamma, p.dist_eps = 2e-3, 1e-2, 1e-6
    p.shadows = getattr(penumbra.Shadows, shadows)
    p.sampling = penumbra.Sampling.exact
    p.shadow_map_size, p.sigma_s, p.gamma_s = 16, 1.0, 0.05
    penumbra.validate(scene)
    return scene


@pytest.fixture(scope="session")
def context():
    return penumbra.Context()


@pytest.fixture(scope="session")
def cli():
    """The penumbra tool of the CMake build ($PENUMBRA_CLI, else build/penumbra)."""
    path = Path(os.environ.get("PENUMBRA_CLI", ROOT / "build" / "penumbra"))
    if not path.is_file():
        pytest.fail(f"the penumbra tool is not built ({path}); run scripts/build.sh")
    return path
