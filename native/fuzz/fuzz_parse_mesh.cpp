// libFuzzer harness for the mesh file readers: parse_mesh(bytes, NFIELD_FUZZ_FORMAT), compiled once per
// format (fuzz_parse_obj, fuzz_parse_off, fuzz_parse_ply; the PLY target covers ASCII and binary bodies,
// which one is chosen by the header in the input).
//
// Accepted outcomes: an nfield::Error, or a MeshData that keeps mesh_io.hpp's promises. A parsed mesh is
// then handed to TriangleMesh as Blender's import path does, so the reader and the ingestion are fuzzed
// together with realistic (file-shaped) input; the mesh_ingestion target covers raw arrays.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "fuzz_checks.hpp"
#include "nfield/errors.hpp"
#include "nfield/mesh_io.hpp"

#ifndef NFIELD_FUZZ_FORMAT
#error "define NFIELD_FUZZ_FORMAT as \"obj\", \"off\" or \"ply\""
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  nfield::MeshData mesh;
  try {
    mesh = nfield::parse_mesh(bytes, NFIELD_FUZZ_FORMAT);
  } catch (const nfield::Error&) {
    return 0;
  }
  nfield_fuzz::check_mesh_data(mesh);
  try {
    const nfield::TriangleMesh cleaned(mesh.positions, mesh.triangles);
    nfield_fuzz::check_mesh_invariants(cleaned);
  } catch (const nfield::Error&) {
  }
  return 0;
}
