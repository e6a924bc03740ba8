"""Fits a sphere to a shadow with Adam on penumbra's gradients. The camera above the ground
sees only the ground (its depth range leaves the sphere out): the sphere's scale and position
reach the loss through its shadow alone. Writes fit_shadow.png: target | start | result."""
import torch
import penumbra
import penumbra.torch as pt

scene = penumbra.bundled_scene()  # a sphere on a ground plane
camera, light = penumbra.Camera(), penumbra.Light()
camera.eye, camera.target, camera.up = (0, 8, 0), (0, 0, 0), (0, 0, -1)
camera.near, camera.far, camera.width, camera.height = 7.9, 8.1, 96, 96
light.type, light.direction = penumbra.LightType.directional, (-0.3, -1, -0.2)
scene.cameras, scene.lights = [camera], [light]
p = scene.params  # shadow edges soft enough to move: docs/applications.md, "Shadow parameters"
p.shadow_map_size, p.light_sigma, p.light_gamma = 128, (1.1 / 128) ** 2, 0.1
p.beta, p.gamma_s = 0.8, 0.2
render = pt.SceneRenderer(scene)
x = render.parameters(torch.float32)
n = len(scene.meshes[0].vertices)  # the sphere's vertices come first, then the ground's
sphere, ground = x["vertices"][:n] - x["vertices"][:n].mean(0), x["vertices"][n:]


def shadow(scale, shift):  # the sphere lifted by 0.6, stretched and moved across the ground
    centre = torch.stack([shift[0], torch.tensor(1.6), shift[1]])
    v = torch.cat([sphere * torch.stack([scale[0], torch.tensor(1.0), scale[1]]) + centre, ground])
    return render(v, x["albedo"], x["lights"], x["ambient"])[0][0]


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
