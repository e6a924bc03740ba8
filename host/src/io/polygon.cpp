// Ear clipping of the mesh readers' polygons (polygon.hpp).
#include "polygon.hpp"

#include <cmath>

namespace penumbra {
namespace {

double cross(const glm::dvec2& a, const glm::dvec2& b) { return a.x * b.y - a.y * b.x; }

// The corners in the polygon's plane, counter-clockwise there: the plane's axes u and w are
// chosen so that u × w is the direction of Newell's normal.
std::vector<glm::dvec2> in_plane(const std::vector<glm::dvec3>& corners) {
  glm::dvec3 normal(0);
  const size_t n = corners.size();
  for (size_t i = 1; i + 1 < n; ++i)  // about the first corner: exact for large coordinates too
    normal += glm::cross(corners[i] - corners[0], corners[i + 1] - corners[0]);
  std::vector<glm::dvec2> out;
  if (!(glm::dot(normal, normal) > 0)) return out;  // no area: nothing to clip by
  normal = glm::normalize(normal);
  const glm::dvec3 other = std::abs(normal.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 u = glm::normalize(glm::cross(other, normal));
  const glm::dvec3 w = glm::cross(normal, u);
  for (const glm::dvec3& c : corners) out.emplace_back(glm::dot(c, u), glm::dot(c, w));
  return out;
}

bool inside_or_on(const glm::dvec2& p, const glm::dvec2& a, const glm::dvec2& b,
                  const glm::dvec2& c) {
  return cross(b - a, p - a) >= 0 && cross(c - b, p - b) >= 0 && cross(a - c, p - c) >= 0;
}

// Whether the corner at position i of `left` (indices into `p`) is an ear: convex, and no
// other corner left inside the triangle it cuts off. Corners at one of the triangle's own
// positions do not count: a polygon with a hole comes as one outline through a doubled
// bridge edge, whose ends appear twice.
bool is_ear(const std::vector<glm::dvec2>& p, const std::vector<int>& left, size_t i) {
  const size_t m = left.size();
  const glm::dvec2 a = p[left[(i + m - 1) % m]], b = p[left[i]], c = p[left[(i + 1) % m]];
  if (cross(b - a, c - b) <= 0) return false;
  for (int k : left)
    if (p[k] != a && p[k] != b && p[k] != c && inside_or_on(p[k], a, b, c)) return false;
  return true;
}

}  // namespace

std::vector<glm::ivec3> triangulate_polygon(const std::vector<glm::dvec3>& corners) {
  const std::vector<glm::dvec2> p = in_plane(corners);
  std::vector<int> left;
  left.reserve(corners.size());
  for (int i = 0; i < static_cast<int>(corners.size()); ++i) left.push_back(i);
  std::vector<glm::ivec3> out;
  while (left.size() > 3) {
    size_t ear = 0;  // when none is found (no area, or not simple): cut the first corner
    if (!p.empty())
      for (size_t i = 0; i < left.size(); ++i)
        if (is_ear(p, left, i)) {
          ear = i;
          break;
        }
    const size_t m = left.size();
    out.emplace_back(left[(ear + m - 1) % m], left[ear], left[(ear + 1) % m]);
    left.erase(left.begin() + static_cast<long>(ear));
  }
  if (left.size() == 3) out.emplace_back(left[0], left[1], left[2]);
  return out;
}

}  // namespace penumbra
