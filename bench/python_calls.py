"""What the Python layer costs, and what a batch saves: penumbra.torch.render against the
module's own Renderer.render_into on the same scene (the C++ call with nothing around it), and
a batch of B shapes in one call against B calls, at 1,312 faces and (the layer) with the ball
made a sphere of 99,224. Medians of alternated runs, and the overhead and speed-up as medians
of the runs' quotients, as JSON. With each batch, the device time of its kernels per shape
(PENUMBRA_PROFILE=1, in a process of its own) and the speed-up a batch would have if it took
only that time (`speedup_bound`: separate calls' time over B times the kernels').

    .venv/bin/python bench/python_calls.py [-o out/bench/python.json] [--repeats 15]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np
import torch

import docfile
import penumbra
import penumbra.torch as pt
from results import KERNEL_LINE


def uv_sphere(rings, centre, radius):
    """A sphere of 4·rings·(rings − 1) faces, wound outwards: rings − 1 rows of 2·rings vertices,
    and the poles."""
    theta = torch.linspace(0, np.pi, rings + 1, dtype=torch.float64)[1:-1, None]
    phi = torch.linspace(0, 2 * np.pi, 2 * rings + 1, dtype=torch.float64)[None, :-1]
    rows = torch.stack([theta.sin() * phi.cos(), theta.cos() + 0 * phi,
                        theta.sin() * phi.sin()], -1).reshape(-1, 3)
    vertices = torch.cat([rows, torch.tensor([[0.0, 1, 0], [0, -1, 0]], dtype=torch.float64)])
    n, r = 2 * rings, torch.arange(rings - 2)[:, None] * 2 * rings
    j, k = torch.arange(n)[None, :], (torch.arange(n)[None, :] + 1) % n
    quads = [torch.stack([r + j, r + n + j, r + k], -1), torch.stack([r + k, r + n + j, r + n + k], -1)]
    last = (rings - 2) * n
    caps = [torch.stack([torch.full((n,), len(rows)), j[0], k[0]], -1),
            torch.stack([torch.full((n,), len(rows) + 1), last + k[0], last + j[0]], -1)]
    faces = torch.cat([q.reshape(-1, 3) for q in quads] + caps)[:, [0, 2, 1]]
    return (vertices * radius + torch.tensor(centre, dtype=torch.float64)).float(), faces


def bundled(size, shadows, rings=0):
    """The bundled sphere and ground (1312 faces) as tensors, its camera at size² pixels; with
    `rings`, the sphere replaced by a uv_sphere of as many rings in its place."""
    scene = penumbra.bundled_scene()
    camera = scene.cameras[0]
    camera.width = camera.height = size
    light = scene.lights[0]
    params = scene.params
    params.shadows = getattr(penumbra.Shadows, shadows)
    vertices = [torch.tensor(m.vertices, dtype=torch.float32) for m in scene.meshes]
    faces = [torch.tensor(m.faces) for m in scene.meshes]
    if rings:
        lo, hi = vertices[0].min(0).values, vertices[0].max(0).values
        vertices[0], faces[0] = uv_sphere(rings, ((lo + hi) / 2).tolist(), float(hi[0] - lo[0]) / 2)
    return vertices, faces, camera, pt.Light.point(light.position, size=light.size), params


def timed(calls, repeats):
    """Each call's median time in ms, the calls alternated so that load falls on all alike, and
    the median over the rounds of each call's time over the first's (robust to the machine's
    speed drifting between rounds)."""
    times = [[] for _ in calls]
    for _ in range(repeats):
        for t, call in zip(times, calls):
            start = time.perf_counter()
            call()
            t.append(1e3 * (time.perf_counter() - start))
    ratios = [statistics.median(a / b for a, b in zip(t, times[0])) for t in times]
    return [statistics.median(t) for t in times], ratios


def layer_overhead(context, repeats, size=256, rings=0):
    vertices, faces, camera, light, params = bundled(size, "hard", rings)
    scene = penumbra.Scene()
    scene.meshes = [penumbra.Mesh(vertices=v.numpy(), faces=f.numpy()) for v, f in zip(vertices, faces)]
    scene.cameras, scene.lights, scene.params = [camera], [light.template()], params
    scene.set_parameters(torch.cat(vertices).numpy(), np.full((len(torch.cat(vertices)), 3), 0.8),
                         torch.stack([light.row(torch.float32)]).numpy(), np.full(3, 0.2))
    renderer = penumbra.Renderer(context)
    out = [np.empty((1, size, size, 3), np.float32), np.empty((1, size, size), np.float32),
           np.empty((1, size, size), np.float32)]
    direct = lambda: renderer.render_into(scene, *out)  # noqa: E731
    through = lambda: pt.render(vertices, faces, camera, light, params=params, context=context)  # noqa: E731
    direct(), through()
    (cpp, python), (_, ratio) = timed([direct, through], repeats)
    return {"size": size, "faces": sum(len(f) for f in faces), "cpp_ms": cpp, "python_ms": python,
            "overhead": ratio - 1}


def batch_calls(context, batch, size, shadows):
    """One call rendering `batch` shapes of the bundled scene, and `batch` calls of one each."""
    vertices, faces, camera, light, params = bundled(size, shadows)
    v = torch.cat(vertices)
    f = torch.cat([faces[0], faces[1] + len(vertices[0])])
    shapes = torch.stack([v * (1 + 0.02 * b) for b in range(batch)])
    one_call = lambda: pt.render(shapes, f, camera, light, params=params, context=context)  # noqa: E731
    separate = lambda: [pt.render(s, f, camera, light, params=params, context=context) for s in shapes]  # noqa: E731
    return one_call, separate


def kernel_ms_per_shape(repeats, batch, size, shadows):
    """The device time of a batch's kernels per shape: `repeats` batched calls after one in a
    new process with PENUMBRA_PROFILE=1 (which prints each kernel's summed time at exit)."""
    env = dict(os.environ, PENUMBRA_PROFILE="1")
    command = [sys.executable, os.path.abspath(__file__), "--kernel-time",
               f"{repeats},{batch},{size},{shadows}"]
    p = subprocess.run(command, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"python_calls: the profiled batch failed ({p.returncode}):\n{p.stderr}")
    rows = [KERNEL_LINE.match(line) for line in p.stderr.splitlines()]
    return sum(float(m.group(2)) for m in rows if m) / ((repeats + 1) * batch)


def batch_gain(context, repeats, batch=8, size=128, shadows="hard"):
    one_call, separate = batch_calls(context, batch, size, shadows)
    one_call(), separate()
    (batched, calls), (_, ratio) = timed([one_call, separate], repeats)
    kernels = kernel_ms_per_shape(repeats, batch, size, shadows)
    return {"batch": batch, "size": size, "shadows": shadows, "batched_ms": batched,
            "separate_ms": calls, "speedup": ratio, "kernel_ms_per_shape": kernels,
            "speedup_bound": calls / (batch * kernels)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="out/bench/python.json")
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--kernel-time", help=argparse.SUPPRESS)  # kernel_ms_per_shape's child
    args = parser.parse_args()
    context = penumbra.Context()
    if args.kernel_time:
        repeats, batch, size, shadows = args.kernel_time.split(",")
        one_call, _ = batch_calls(context, int(batch), int(size), shadows)
        for _ in range(int(repeats) + 1):
            one_call()
        return
    results = {"device": context.info.name, "load": os.getloadavg()[0],
               "layer": layer_overhead(context, args.repeats),
               "layer_dense": layer_overhead(context, args.repeats, rings=158),
               "batch": [batch_gain(context, args.repeats, shadows=s) for s in ("none", "hard")]}
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    docfile.write_text(args.output, json.dumps(results, indent=1))
    print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
