#pragma once
// What the mesh readers share (internal): degenerate faces dropped or refused.
#include <functional>
#include <string>

#include "penumbra/io.hpp"

namespace penumbra {

// Drops or refuses (`policy`) the faces of `mesh` that repeat a corner or have no area.
// `file` names the file in messages ("OBJ file 'a.obj'"); `place(f)` says where face f comes
// from in it ("line 12"). A mesh with no face left is refused.
void drop_degenerate_faces(Mesh& mesh, DegenerateFacePolicy policy, const std::string& file,
                           const std::function<std::string(size_t)>& place);

}  // namespace penumbra
