// Readers for triangle and polygon mesh files: OBJ (v / f lines; polygons fan-triangulated), OFF and PLY
// (ASCII and binary little-endian). Output faces keep the input's face order; for polygons each triangle
// records the index of the polygon it came from. Malformed files throw InputError naming file and line.
#pragma once
#include <string>
#include <vector>

#include "nfield/mesh.hpp"

namespace nfield {

struct MeshData {
  Positions positions;            ///< V x 3
  Triangles triangles;            ///< T x 3, fan-triangulated polygons, in input face order
  std::vector<int> triangle_polygon;  ///< T entries: index of the input polygon of each triangle
  int num_polygons = 0;
};

/// Dispatches on the extension (.obj, .off, .ply; case-insensitive). Throws InputError.
MeshData read_mesh(const std::string& path);
MeshData read_obj(const std::string& path);
MeshData read_off(const std::string& path);
MeshData read_ply(const std::string& path);
/// Parse from memory (used by the fuzzer and tests); format is "obj", "off" or "ply".
MeshData parse_mesh(const std::string& bytes, const std::string& format);

}  // namespace nfield
