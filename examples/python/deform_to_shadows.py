"""Deforms a sphere to fit target shadows, as PyTorch3D's "deform a source mesh to fit target
silhouettes", with one change: the only signal is the shadows three lights (red, green, blue)
cast on the ground. The camera above the ground sees only the ground (its depth range leaves
the shape out), so each colour channel holds one light's shadow. Optimises per-vertex offsets
with Adam, with a Laplacian smoothness term. Writes deform_to_shadows.png: target | start |
result."""
import torch
import penumbra
import penumbra.torch as pt

sphere, faces = pt.load_mesh(penumbra.data_dir() / "meshes" / "icosphere.obj")
ground = torch.tensor([[-6, 0, -6], [-6, 0, 6], [6, 0, 6], [6, 0, -6]], dtype=torch.float32)
ground_faces = torch.tensor([[0, 1, 2], [0, 2, 3]])
lift = torch.tensor([0.0, 1.6, 0.0])
camera = pt.Camera.look_at((0, 8, 0), (0, 0, 0), up=(0, 0, -1), fov=60, width=96, height=96,
                           near=7.9, far=8.1)
lights = [pt.Light.directional(torch.tensor(d), color=c) for d, c in
          (([-0.5, -1, 0.1], (1, 0, 0)), ([0.5, -1, 0.3], (0, 1, 0)), ([0.0, -1, -0.6], (0, 0, 1)))]
params = penumbra.RenderParams()  # shadow edges soft enough to move: docs/applications.md
params.shadows, params.shadow_map_size = penumbra.Shadows.hard, 128
params.light_sigma, params.light_gamma = (1.1 / 128) ** 2, 0.1


def shadows(shape):  # the ground's colour: each channel lit by one light
    colour, _, _ = pt.render([shape + lift, ground], [faces, ground_faces], camera, lights,
                             params=params, ambient=0.0)
    return colour[0]


x, y, z = sphere.unbind(1)  # the target: a stretched, bent sphere with a bump
target_shape = torch.stack([1.3 * x, 0.8 * y + 0.3 * x * x, 0.7 * z], 1)
target_shape = target_shape + 0.35 * torch.relu(x - 0.5)[:, None] * torch.tensor([1.0, 0.0, 0.0])
target = shadows(target_shape).detach()

edges = torch.cat([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).unique(dim=0)
degree = torch.zeros(len(sphere)).index_add_(0, edges[:, 0], torch.ones(len(edges)))


def laplacian(v):  # each vertex against the mean of its neighbours
    mean = torch.zeros_like(v).index_add_(0, edges[:, 0], v[edges[:, 1]]) / degree[:, None]
    return ((v - mean) ** 2).sum(1).mean()


offsets = torch.zeros_like(sphere, requires_grad=True)
optimizer = torch.optim.Adam([offsets], lr=0.01)
start = shadows(sphere).detach()
for step in range(150):
    optimizer.zero_grad()
    shape = sphere + offsets
    loss = ((shadows(shape) - target) ** 2).mean() + 0.5 * laplacian(shape)
    loss.backward()
    optimizer.step()
result = shadows(sphere + offsets).detach()
error = lambda image: ((image - target) ** 2).mean().item()  # noqa: E731
print(f"deform_to_shadows: shadow error {error(start):.2e} at the start, {error(result):.2e} fitted")
penumbra.save_png(torch.cat([target, start, result], 1).numpy(), "deform_to_shadows.png")
