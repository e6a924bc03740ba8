"""Fits a sphere to a shadow with Adam on penumbra's gradients. The camera above the ground
sees only the ground (its depth range leaves the sphere out): the sphere's scale and position
reach the loss through its shadow alone. Writes fit_shadow.png: target | start | result."""
import torch
import penumbra
import penumbra.torch as pt

sphere, faces = pt.load_mesh(penumbra.data_dir() / "meshes" / "icosphere.obj")
ground, ground_faces = pt.load_mesh(penumbra.data_dir() / "meshes" / "plane.obj")
camera = pt.Camera.look_at((0, 8, 0), (0, 0, 0), up=(0, 0, -1), fov=40, width=96, height=96,
                           near=7.9, far=8.1)
light = pt.Light.directional((-0.3, -1, -0.2))
params = penumbra.RenderParams()  # shadow edges soft enough to move: docs/applications.md
params.shadows, params.shadow_map_size = penumbra.Shadows.hard, 128
params.light_sigma, params.light_gamma = (1.1 / 128) ** 2, 0.1


def shadow(scale, shift):  # the sphere lifted by 0.6, stretched and moved across the ground
    centre = torch.stack([shift[0], torch.tensor(1.6), shift[1]])
    v = sphere * torch.stack([scale[0], torch.tensor(1.0), scale[1]]) + centre
    colour, _, _ = pt.render([v, ground], [faces, ground_faces], camera, light, params=params)
    return colour[0]


target = shadow(torch.tensor([1.4, 0.7]), torch.tensor([0.3, -0.2]))
log_scale, shift = torch.zeros(2, requires_grad=True), torch.zeros(2, requires_grad=True)
start = shadow(log_scale.exp(), shift).detach()
optimizer = torch.optim.Adam([log_scale, shift], lr=0.02)
for step in range(100):
    optimizer.zero_grad()
    loss = ((shadow(log_scale.exp(), shift) - target) ** 2).mean()
    loss.backward()
    optimizer.step()
print(f"fit_shadow: loss={loss.item():.1e} scale={log_scale.exp().tolist()} shift={shift.tolist()}")
result = shadow(log_scale.exp(), shift).detach()
penumbra.save_png(torch.cat([target, start, result], 1).numpy(), "fit_shadow.png")
