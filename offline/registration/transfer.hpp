#pragma once
/// Transfer of surfaces embedded in the template (seed 003 §4.3: a high-resolution, textured liver
/// surface carried by the registration of a coarser template). Every vertex of the surface is a
/// material point of the template's tet mesh; its deformed position replaces it.
///
/// OBJ files are rewritten line by line: only the "v x y z" lines change, so texture coordinates
/// (vt), materials (mtllib, usemtl), groups and faces with their vt indices are kept as they are;
/// normals (vn) are dropped, since they no longer match, and so are the faces' normal indices.
/// Other formats (.off, .stl, .ply) are read and written back in their format.

#include <Eigen/Core>
#include <functional>
#include <string>

namespace sinew::offline {

/// Maps a template-frame point (user units) to its deformed position, or throws
/// RegistrationInputError naming the point when it is not inside or near the template mesh.
using PointTransfer = std::function<Eigen::Vector3d(const Eigen::Vector3d&, long index)>;

/// Writes in_path's surface, every vertex moved by transfer, to out_path (atomically; nothing is
/// written when out_path is empty, e.g. to embed and check the vertices first). Throws
/// RegistrationInputError (offline/registration/registration_case.hpp) for unreadable input, with
/// file:line for bad OBJ lines. Returns the number of vertices moved.
long transfer_surface(const std::string& in_path, const std::string& out_path,
                      const PointTransfer& transfer);

}  // namespace sinew::offline
