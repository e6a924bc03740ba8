// Mesh regularisers (math.md §9) with analytic gradients with respect to the vertices: uniform
// Laplacian, edge length and normal consistency; and the connectivity they need.
#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <utility>

#include "penumbra/error.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {
namespace {

void prepare(std::vector<glm::dvec3>* grad, size_t n, const char* what) {
  if (grad == nullptr) return;
  if (grad->empty()) grad->assign(n, glm::dvec3(0.0));
  if (grad->size() != n)
    throw Error(std::string(what) + ": gradient has " + std::to_string(grad->size()) +
                " entries for " + std::to_string(n) + " vertices");
}

}  // namespace

Topology topology(const std::vector<glm::ivec3>& faces, size_t vertex_count) {
  Topology t;
  t.neighbours.assign(vertex_count, {});
  std::map<std::pair<int, int>, std::vector<int>> edge_faces;
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int a = faces[f][k], b = faces[f][(k + 1) % 3];
      if (a < 0 || b < 0 || size_t(a) >= vertex_count || size_t(b) >= vertex_count)
        throw Error("topology: face " + std::to_string(f) + " has a vertex index out of range");
      if (a > b) std::swap(a, b);
      edge_faces[{a, b}].push_back(int(f));
    }
  }
  t.edges.reserve(edge_faces.size());
  for (const auto& [edge, fs] : edge_faces) {
    t.edges.emplace_back(edge.first, edge.second);
    t.neighbours[size_t(edge.first)].push_back(edge.second);
    t.neighbours[size_t(edge.second)].push_back(edge.first);
    if (fs.size() == 2) t.hinges.emplace_back(fs[0], fs[1]);
  }
  for (auto& n : t.neighbours) std::sort(n.begin(), n.end());
  return t;
}

double laplacian_loss(const std::vector<glm::dvec3>& v, const Topology& topo,
                      std::vector<glm::dvec3>* grad, double weight) {
  if (topo.neighbours.size() != v.size())
    throw Error("laplacian_loss: topology of " + std::to_string(topo.neighbours.size()) +
                " vertices for " + std::to_string(v.size()));
  prepare(grad, v.size(), "laplacian_loss");
  double sum = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    const auto& nb = topo.neighbours[i];
    if (nb.empty()) continue;
    glm::dvec3 mean(0.0);
    for (int j : nb) mean += v[size_t(j)];
    const double inv = 1.0 / double(nb.size());
    const glm::dvec3 d = v[i] - mean * inv;
    sum += glm::dot(d, d);
    if (grad != nullptr) {
      const glm::dvec3 g = 2.0 * weight * d;
      (*grad)[i] += g;
      for (int j : nb) (*grad)[size_t(j)] -= g * inv;
    }
  }
  return weight * sum;
}

double edge_loss(const std::vector<glm::dvec3>& v, const Topology& topo, EdgeLoss kind,
                 std::vector<glm::dvec3>* grad, double weight) {
  prepare(grad, v.size(), "edge_loss");
  const size_t ne = topo.edges.size();
  if (ne == 0) return 0.0;
  const double inv_e = 1.0 / double(ne);
  if (kind == EdgeLoss::SquaredLength) {
    double sum = 0;
    for (const glm::ivec2& e : topo.edges) {
      const glm::dvec3 d = v[size_t(e.x)] - v[size_t(e.y)];
      sum += glm::dot(d, d);
      if (grad != nullptr) {
        const glm::dvec3 g = 2.0 * weight * inv_e * d;
        (*grad)[size_t(e.x)] += g;
        (*grad)[size_t(e.y)] -= g;
      }
    }
    return weight * sum * inv_e;
  }
  // Variance: dL/dℓ_e = 2(ℓ_e − mean)/E (the mean's own dependence sums to zero).
  std::vector<double> len(ne);
  double mean = 0;
  for (size_t k = 0; k < ne; ++k) {
    len[k] = glm::length(v[size_t(topo.edges[k].x)] - v[size_t(topo.edges[k].y)]);
    mean += len[k];
  }
  mean *= inv_e;
  double var = 0;
  for (size_t k = 0; k < ne; ++k) {
    const double dl = len[k] - mean;
    var += dl * dl;
    if (grad != nullptr && len[k] > 0) {
      const glm::ivec2 e = topo.edges[k];
      const glm::dvec3 dir = (v[size_t(e.x)] - v[size_t(e.y)]) / len[k];
      const glm::dvec3 g = 2.0 * weight * inv_e * dl * dir;
      (*grad)[size_t(e.x)] += g;
      (*grad)[size_t(e.y)] -= g;
    }
  }
  return weight * var * inv_e;
}

double normal_consistency_loss(const std::vector<glm::dvec3>& v,
                               const std::vector<glm::ivec3>& faces, const Topology& topo,
                               std::vector<glm::dvec3>* grad, double weight) {
  prepare(grad, v.size(), "normal_consistency_loss");
  // Unnormalised normals c = (b − a) × (c − a), their lengths and unit normals.
  const size_t nf = faces.size();
  std::vector<glm::dvec3> n(nf);
  std::vector<double> len(nf);
  for (size_t f = 0; f < nf; ++f) {
    const glm::ivec3 F = faces[f];
    const glm::dvec3 c =
        glm::cross(v[size_t(F.y)] - v[size_t(F.x)], v[size_t(F.z)] - v[size_t(F.x)]);
    len[f] = glm::length(c);
    n[f] = len[f] > 0 ? c / len[f] : glm::dvec3(0.0);
  }
  // dL/d(unit normal), summed per face first.
  std::vector<glm::dvec3> gn(grad != nullptr ? nf : 0, glm::dvec3(0.0));
  double sum = 0;
  for (const glm::ivec2& h : topo.hinges) {
    const size_t f0 = size_t(h.x), f1 = size_t(h.y);
    if (!(len[f0] > 0) || !(len[f1] > 0)) continue;
    sum += 1.0 - glm::dot(n[f0], n[f1]);
    if (grad != nullptr) {
      gn[f0] -= weight * n[f1];
      gn[f1] -= weight * n[f0];
    }
  }
  if (grad != nullptr) {
    for (size_t f = 0; f < nf; ++f) {
      if (!(len[f] > 0)) continue;
      // n = c/|c|: dL/dc = (I − n nᵀ) dL/dn / |c|.
      const glm::dvec3 gc = (gn[f] - n[f] * glm::dot(n[f], gn[f])) / len[f];
      // c = e1 × e2, e1 = b − a, e2 = c − a: dL/de1 = e2 × gc, dL/de2 = gc × e1.
      const glm::ivec3 F = faces[f];
      const glm::dvec3 e1 = v[size_t(F.y)] - v[size_t(F.x)], e2 = v[size_t(F.z)] - v[size_t(F.x)];
      const glm::dvec3 g1 = glm::cross(e2, gc), g2 = glm::cross(gc, e1);
      (*grad)[size_t(F.y)] += g1;
      (*grad)[size_t(F.z)] += g2;
      (*grad)[size_t(F.x)] -= g1 + g2;
    }
  }
  return weight * sum;
}

}  // namespace penumbra::optim
