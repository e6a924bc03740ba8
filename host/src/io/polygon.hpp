#pragma once
// Polygons of mesh files as triangles (internal to the mesh readers).
#include <vector>

#include <glm/glm.hpp>

namespace penumbra {

// The triangles of a polygon given by its corners in order, as indices into `corners`, wound
// as the polygon is. Ear clipping in the plane of the polygon (Newell's normal), so that a
// concave polygon keeps its shape where a fan would cover more than it. A polygon that is not
// simple still gives corners.size() - 2 triangles, some of them possibly overlapping.
std::vector<glm::ivec3> triangulate_polygon(const std::vector<glm::dvec3>& corners);

}  // namespace penumbra
