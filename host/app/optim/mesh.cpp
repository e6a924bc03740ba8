// Mesh refinement (midpoint subdivision), the visual hull of a set of silhouettes and the
// surface-nets mesh of an occupancy grid.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "penumbra/error.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {

Mesh subdivide(const Mesh& mesh) {
  Mesh out;
  out.name = mesh.name;
  out.albedo_mode = mesh.albedo_mode;
  out.vertices = mesh.vertices;
  const bool per_vertex = mesh.albedo_mode == AlbedoMode::PerVertex;
  if (per_vertex) out.albedo = mesh.albedo;
  std::map<std::pair<int, int>, int> mid;
  auto midpoint = [&](int a, int b) {
    const std::pair<int, int> key = a < b ? std::make_pair(a, b) : std::make_pair(b, a);
    auto it = mid.find(key);
    if (it != mid.end()) return it->second;
    const int index = int(out.vertices.size());
    out.vertices.push_back(0.5 * (mesh.vertices[size_t(a)] + mesh.vertices[size_t(b)]));
    if (per_vertex && mesh.albedo.size() == mesh.vertices.size())
      out.albedo.push_back(0.5 * (mesh.albedo[size_t(a)] + mesh.albedo[size_t(b)]));
    mid.emplace(key, index);
    return index;
  };
  out.faces.reserve(mesh.faces.size() * 4);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const glm::ivec3 F = mesh.faces[f];
    const int ab = midpoint(F.x, F.y), bc = midpoint(F.y, F.z), ca = midpoint(F.z, F.x);
    out.faces.emplace_back(F.x, ab, ca);
    out.faces.emplace_back(ab, F.y, bc);
    out.faces.emplace_back(ca, bc, F.z);
    out.faces.emplace_back(ab, bc, ca);
    if (!per_vertex && f < mesh.albedo.size())
      for (int k = 0; k < 4; ++k) out.albedo.push_back(mesh.albedo[f]);
  }
  return out;
}

double mean_edge_length(const Mesh& mesh) {
  const Topology t = topology(mesh.faces, mesh.vertices.size());
  if (t.edges.empty()) return 0.0;
  double sum = 0;
  for (const glm::ivec2& e : t.edges)
    sum += glm::length(mesh.vertices[size_t(e.x)] - mesh.vertices[size_t(e.y)]);
  return sum / double(t.edges.size());
}

std::vector<unsigned char> visual_hull(const std::vector<Image>& targets,
                                       const std::vector<glm::dvec3>& directions,
                                       double half_height, int n, double half) {
  if (targets.size() != directions.size())
    throw Error("visual_hull: " + std::to_string(targets.size()) + " targets for " +
                std::to_string(directions.size()) + " directions");
  if (n < 1) throw Error("visual_hull: grid size must be positive");
  std::vector<unsigned char> occ(size_t(n) * n * n, 1);
  const double h = 2.0 * half / n;
  for (size_t k = 0; k < targets.size(); ++k) {
    const Image& t = targets[k];
    const glm::dvec3 fwd = glm::normalize(directions[k]);
    const glm::dvec3 right = glm::normalize(glm::cross(fwd, view_up(fwd)));
    const glm::dvec3 up = glm::cross(right, fwd);
    const double W = t.width, H = t.height;
    for (int z = 0; z < n; ++z)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
          unsigned char& o = occ[(size_t(z) * n + y) * n + x];
          if (!o) continue;
          const glm::dvec3 X(-half + (x + 0.5) * h, -half + (y + 0.5) * h, -half + (z + 0.5) * h);
          // Screen units (math.md §1): image height spans 2; pixel centres at (2p + 1 − W)/H.
          const double sx = glm::dot(X, right) / half_height, sy = glm::dot(X, up) / half_height;
          const double px = std::floor((sx * H + W) / 2), py = std::floor((H - sy * H) / 2);
          if (px < 0 || py < 0 || px >= W || py >= H || !(t.at(int(px), int(py)) > 0.5)) o = 0;
        }
  }
  return occ;
}

namespace {

// The occupancy grid read on a padded grid of samples p ∈ [0, n + 1] per axis (0 and n + 1
// outside); sample p is voxel p − 1.
struct PaddedGrid {
  const std::vector<unsigned char>& occ;
  int n;
  bool inside(int x, int y, int z) const {
    if (x < 1 || y < 1 || z < 1 || x > n || y > n || z > n) return false;
    return occ[(size_t(z - 1) * n + (y - 1)) * n + (x - 1)] != 0;
  }
};

// One vertex in every dual cell (c ∈ [0, n] per axis, corners c and c + 1) whose corners are
// not all inside or all outside, at the mean of the midpoints of its edges that cross the
// surface. Returns each cell's vertex in `mesh` (−1: none), indexed (z·(n + 1) + y)·(n + 1) + x.
std::vector<int> place_cell_vertices(const PaddedGrid& g, double half, Mesh& mesh) {
  static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0},
                                   {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
  static const int edge[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                  {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  const double h = 2.0 * half / g.n;
  const int C = g.n + 1;
  std::vector<int> cell_vertex(size_t(C) * C * C, -1);
  for (int z = 0; z < C; ++z)
    for (int y = 0; y < C; ++y)
      for (int x = 0; x < C; ++x) {
        bool in[8];
        int count = 0;
        for (int k = 0; k < 8; ++k) {
          in[k] = g.inside(x + corner[k][0], y + corner[k][1], z + corner[k][2]);
          count += in[k] ? 1 : 0;
        }
        if (count == 0 || count == 8) continue;
        glm::dvec3 sum(0.0);
        int crossings = 0;
        for (const auto& e : edge) {
          if (in[e[0]] == in[e[1]]) continue;
          sum +=
              0.5 * glm::dvec3(corner[e[0]][0] + corner[e[1]][0], corner[e[0]][1] + corner[e[1]][1],
                               corner[e[0]][2] + corner[e[1]][2]);
          ++crossings;
        }
        const glm::dvec3 local = sum / double(crossings);  // in [0, 1]³ of the cell
        // Sample p sits at −half + (p − 0.5)·h.
        const glm::dvec3 p = glm::dvec3(x, y, z) + local;
        cell_vertex[(size_t(z) * C + y) * C + x] = int(mesh.vertices.size());
        mesh.vertices.push_back(glm::dvec3(-half) + (p - 0.5) * h);
      }
  return cell_vertex;
}

// The quad a b c d as two triangles, split along the shorter diagonal.
void add_quad(Mesh& mesh, int a, int b, int c, int d) {
  const auto& V = mesh.vertices;
  if (glm::length(V[size_t(a)] - V[size_t(c)]) <= glm::length(V[size_t(b)] - V[size_t(d)])) {
    mesh.faces.emplace_back(a, b, c);
    mesh.faces.emplace_back(a, c, d);
  } else {
    mesh.faces.emplace_back(a, b, d);
    mesh.faces.emplace_back(b, c, d);
  }
}

// Every sample edge (s, s + e_axis) between an inside and an outside sample: a quad of the
// four cells around it, wound so that its normal points from inside to outside.
void add_quads(const PaddedGrid& g, const std::vector<int>& cell_vertex, Mesh& mesh) {
  const int P = g.n + 2, C = g.n + 1;
  auto cell = [&](int x, int y, int z) { return cell_vertex[(size_t(z) * C + y) * C + x]; };
  for (int z = 0; z < P; ++z)
    for (int y = 0; y < P; ++y)
      for (int x = 0; x < P; ++x) {
        const int s[3] = {x, y, z};
        for (int axis = 0; axis < 3; ++axis) {
          int t[3] = {x, y, z};
          t[axis] += 1;
          if (t[axis] >= P) continue;
          const bool a = g.inside(s[0], s[1], s[2]), b = g.inside(t[0], t[1], t[2]);
          if (a == b) continue;
          const int bi = (axis + 1) % 3, ci = (axis + 2) % 3;
          // The four cells share the edge: cell index along `axis` is s[axis]; along the other
          // two it is s − 1 or s.
          if (s[bi] < 1 || s[ci] < 1 || s[bi] > g.n || s[ci] > g.n) continue;  // never on the pad
          int q[4];
          const int db[4] = {-1, 0, 0, -1}, dc[4] = {-1, -1, 0, 0};
          for (int k = 0; k < 4; ++k) {
            int c[3];
            c[axis] = s[axis];
            c[bi] = s[bi] + db[k];
            c[ci] = s[ci] + dc[k];
            q[k] = cell(c[0], c[1], c[2]);
          }
          if (a)  // inside at the lower end: normal along +axis
            add_quad(mesh, q[0], q[1], q[2], q[3]);
          else
            add_quad(mesh, q[3], q[2], q[1], q[0]);
        }
      }
}

// Laplacian smoothing (λ = 0.5) rounds off the voxel staircase.
void smooth(Mesh& mesh, int steps) {
  const Topology topo = topology(mesh.faces, mesh.vertices.size());
  for (int step = 0; step < steps; ++step) {
    std::vector<glm::dvec3> next = mesh.vertices;
    for (size_t i = 0; i < next.size(); ++i) {
      const auto& nb = topo.neighbours[i];
      if (nb.empty()) continue;
      glm::dvec3 mean(0.0);
      for (int j : nb) mean += mesh.vertices[size_t(j)];
      next[i] = 0.5 * mesh.vertices[i] + 0.5 * mean / double(nb.size());
    }
    mesh.vertices.swap(next);
  }
}

}  // namespace

Mesh surface_nets(const std::vector<unsigned char>& occ, int n, double half, int smooth_steps,
                  glm::dvec3 albedo) {
  if (occ.size() != size_t(n) * n * n)
    throw Error("surface_nets: occupancy of " + std::to_string(occ.size()) +
                " values for a grid of " + std::to_string(n) + "^3");
  const PaddedGrid grid{occ, n};
  Mesh mesh;
  mesh.name = "hull";
  const std::vector<int> cell_vertex = place_cell_vertices(grid, half, mesh);
  add_quads(grid, cell_vertex, mesh);
  if (mesh.faces.empty()) throw Error("surface_nets: the occupancy grid is empty");
  smooth(mesh, smooth_steps);
  mesh.albedo.assign(mesh.vertices.size(), albedo);
  mesh.albedo_mode = AlbedoMode::PerVertex;
  return mesh;
}

}  // namespace penumbra::optim
