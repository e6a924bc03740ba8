"""What the Python layer costs, and what a batch saves: penumbra.torch.render against the
module's own Renderer.render_into on the same scene (the C++ call with nothing around it), and
a batch of B shapes in one call against B calls. Medians of alternated runs, as JSON.

    .venv/bin/python bench/python_calls.py [-o out/bench/python.json] [--repeats 15]
"""
import argparse
import json
import os
import statistics
import time

import numpy as np
import torch

import penumbra
import penumbra.torch as pt


def bundled(size, shadows):
    """The bundled sphere and ground (1312 faces) as tensors, its camera at size² pixels."""
    scene = penumbra.bundled_scene()
    camera = scene.cameras[0]
    camera.width = camera.height = size
    light = scene.lights[0]
    params = scene.params
    params.shadows = getattr(penumbra.Shadows, shadows)
    vertices = [torch.tensor(m.vertices, dtype=torch.float32) for m in scene.meshes]
    faces = [torch.tensor(m.faces) for m in scene.meshes]
    return vertices, faces, camera, pt.Light.point(light.position, size=light.size), params


def median_ms(calls, repeats):
    """Each call's median time in ms, the calls alternated so that load falls on all alike."""
    times = [[] for _ in calls]
    for _ in range(repeats):
        for t, call in zip(times, calls):
            start = time.perf_counter()
            call()
            t.append(1e3 * (time.perf_counter() - start))
    return [statistics.median(t) for t in times]


def layer_overhead(context, repeats, size=256):
    vertices, faces, camera, light, params = bundled(size, "hard")
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
    cpp, python = median_ms([direct, through], repeats)
    return {"size": size, "faces": sum(len(f) for f in faces), "cpp_ms": cpp, "python_ms": python,
            "overhead": python / cpp - 1}


def batch_gain(context, repeats, batch=8, size=128, shadows="hard"):
    vertices, faces, camera, light, params = bundled(size, shadows)
    v = torch.cat(vertices)
    f = torch.cat([faces[0], faces[1] + len(vertices[0])])
    shapes = torch.stack([v * (1 + 0.02 * b) for b in range(batch)])
    one_call = lambda: pt.render(shapes, f, camera, light, params=params, context=context)  # noqa: E731
    separate = lambda: [pt.render(s, f, camera, light, params=params, context=context) for s in shapes]  # noqa: E731
    one_call(), separate()
    batched, calls = median_ms([one_call, separate], repeats)
    return {"batch": batch, "size": size, "shadows": shadows, "batched_ms": batched,
            "separate_ms": calls, "speedup": calls / batched}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="out/bench/python.json")
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    context = penumbra.Context()
    results = {"device": context.info.name, "load": os.getloadavg()[0],
               "layer": layer_overhead(context, args.repeats),
               "batch": [batch_gain(context, args.repeats, shadows=s) for s in ("none", "hard")]}
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    with open(args.output + ".tmp", "w") as f:
        json.dump(results, f, indent=1)
    os.replace(args.output + ".tmp", args.output)
    print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
