// The scene's meshes as the device reads them, and what a render keeps of the last render's
// (renderer_impl.hpp: Packed, pack, same_faces).
#include <cstring>
#include <type_traits>
#include <vector>

#include "renderer_impl.hpp"

namespace penumbra {

// Written in place over the previous call's storage: at 100k faces, fresh vectors filled by
// insert() made this 2.5-6 ms of every render, most of it page faults.
void pack(const Scene& s, Packed& p, Kept kept) {
  p.nv = p.nf = p.na = 0;
  p.vertex_offset.clear();
  p.face_offset.clear();
  p.albedo_offset.clear();
  for (auto& m : s.meshes) {
    p.vertex_offset.push_back(size_t(p.nv));
    p.face_offset.push_back(size_t(p.nf));
    p.albedo_offset.push_back(size_t(p.na));
    p.nv += int(m.vertices.size()), p.nf += int(m.faces.size()), p.na += int(m.albedo.size());
  }
  p.faces.resize(size_t(p.nf) * 4);
  p.albedo.resize(size_t(p.nf) * 12);
  for (size_t mi = 0; mi < s.meshes.size(); ++mi) {
    const Mesh& m = s.meshes[mi];
    const size_t f0 = p.face_offset[mi];
    for (size_t f = 0; kept == Kept::Nothing && f < m.faces.size(); ++f) {
      int* face = &p.faces[(f0 + f) * 4];
      for (int k = 0; k < 3; ++k) face[k] = m.faces[f][k] + int(p.vertex_offset[mi]);
      face[3] = 0;
    }
    for (size_t f = 0; kept != Kept::FacesAndAlbedo && f < m.faces.size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const glm::ivec3& F = m.faces[f];
        const glm::dvec3& a = m.albedo_mode == AlbedoMode::PerFace ? m.albedo[f] : m.albedo[F[k]];
        double* at = &p.albedo[((f0 + f) * 3 + size_t(k)) * 4];
        at[0] = a.x, at[1] = a.y, at[2] = a.z, at[3] = 0;
      }
  }
}

void write_vertices(Context& ctx, Precision p, cl::Buffer& buffer, const std::vector<Mesh>& meshes,
                    size_t nv) {
  detail::fill_reals(ctx, p, buffer, nv * 4, [&](auto* at) {
    using Real = std::remove_pointer_t<decltype(at)>;
    for (const Mesh& m : meshes)
      for (const glm::dvec3& v : m.vertices) {
        at[0] = Real(v.x), at[1] = Real(v.y), at[2] = Real(v.z), at[3] = 0;
        at += 4;
      }
  });
}

namespace {
// One array (a copy of the other, O(1)), or the same bits (memcmp: at a million faces 3.1 ms,
// against 4.2 element by element through glm's operator==). An albedo that differs only as −0
// from +0 is packed again, which changes nothing.
template <class T>
bool same_values(const SharedArray<T>& a, const SharedArray<T>& b) {
  static_assert(std::has_unique_object_representations_v<T> || std::is_same_v<T, glm::dvec3>);
  return a.shares(b) ||
         (a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}
}  // namespace

bool same_faces(const std::vector<Mesh>& a, const std::vector<Mesh>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].vertices.size() != b[i].vertices.size() || !same_values(a[i].faces, b[i].faces) ||
        a[i].albedo_mode != b[i].albedo_mode || a[i].albedo.size() != b[i].albedo.size())
      return false;
  return true;
}

bool same_albedo(const std::vector<Mesh>& a, const std::vector<Mesh>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (!same_values(a[i].albedo, b[i].albedo)) return false;
  return true;
}

}  // namespace penumbra
