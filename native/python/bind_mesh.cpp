// Binding of the mesh area: nfield._native.Mesh (mesh.hpp) and read_mesh (mesh_io.hpp).
#include <string>

#include "binding_support.hpp"
#include "nfield/mesh.hpp"
#include "nfield/mesh_io.hpp"

namespace nfield::python {
namespace {

py::dict report_to_dict(const MeshReport& r) {
  return named("num_input_vertices", r.num_input_vertices, "num_input_faces", r.num_input_faces,
               "unused_vertices", r.unused_vertices, "degenerate_faces", r.degenerate_faces, "sliver_faces",
               r.sliver_faces, "duplicate_faces", r.duplicate_faces, "nonmanifold_edges", r.nonmanifold_edges,
               "nonmanifold_vertices", r.nonmanifold_vertices, "flipped_faces", r.flipped_faces,
               "num_orientation_cuts", r.num_orientation_cuts, "num_boundary_edges", r.num_boundary_edges,
               "num_boundary_loops", r.num_boundary_loops, "num_components", r.num_components,
               "euler_characteristic", r.euler_characteristic, "summary", r.summary());
}

void require_vertex(const TriangleMesh& m, int v) {
  if (v < 0 || v >= m.num_vertices()) throw InputError("vertex " + std::to_string(v) + " is out of range");
}

}  // namespace

void bind_mesh(py::module_& m) {
  py::class_<TriangleMesh, std::shared_ptr<TriangleMesh>>(m, "Mesh", py::module_local(), "Validated, cleaned triangle mesh")
      .def(py::init([](const DoubleArray& positions, const IndexArray& faces) {
             Positions P = to_positions(positions);
             Triangles T = to_triangles(faces);
             return without_gil([&] { return std::make_shared<TriangleMesh>(P, T); });
           }),
           py::arg("positions"), py::arg("faces"))
      .def_property_readonly("num_vertices", &TriangleMesh::num_vertices)
      .def_property_readonly("num_faces", &TriangleMesh::num_faces)
      .def_property_readonly("num_active_faces", &TriangleMesh::num_active_faces)
      .def_property_readonly("positions", [](const TriangleMesh& m) { return from_rows(m.positions()); })
      .def_property_readonly("faces", [](const TriangleMesh& m) { return from_rows(m.faces()); })
      .def_property_readonly("face_active", [](const TriangleMesh& m) {
        py::array_t<bool> out(m.num_faces());
        for (int f = 0; f < m.num_faces(); ++f) out.mutable_data()[f] = m.face_active(f);
        return out;
      })
      .def_property_readonly("face_normals", [](const TriangleMesh& m) {
        std::vector<Eigen::Vector3d> n(m.num_faces());
        for (int f = 0; f < m.num_faces(); ++f) n[f] = m.face_normal(f);
        return from_vec3(n);
      })
      .def_property_readonly("face_areas", [](const TriangleMesh& m) {
        py::array_t<double> out(m.num_faces());
        for (int f = 0; f < m.num_faces(); ++f) out.mutable_data()[f] = m.face_area(f);
        return out;
      })
      .def_property_readonly("face_component", [](const TriangleMesh& m) { return from_std(m.face_component()); })
      .def_property_readonly("num_components", [](const TriangleMesh& m) { return m.report().num_components; })
      .def_property_readonly("total_area", &TriangleMesh::total_area)
      .def_property_readonly("bounding_box_diagonal", &TriangleMesh::bounding_box_diagonal)
      .def_property_readonly("content_hash", &TriangleMesh::content_hash)
      .def("report", [](const TriangleMesh& m) { return report_to_dict(m.report()); })
      .def("vertex_is_interior", [](const TriangleMesh& m, int v) {
        require_vertex(m, v);
        return m.vertex_is_interior(v);
      })
      .def("angle_defect", [](const TriangleMesh& m, int v) {
        require_vertex(m, v);
        return m.angle_defect(v);
      })
      .def("vertex_ring_faces", [](const TriangleMesh& m, int v) {
        require_vertex(m, v);
        return m.vertex_ring_faces(v);
      })
      .def("dual_edges", [](const TriangleMesh& m) {
        const auto& e = m.dual_edges();
        py::array_t<int> out({static_cast<py::ssize_t>(e.size()), py::ssize_t(4)});
        int* d = out.mutable_data();
        for (size_t i = 0; i < e.size(); ++i) {
          d[4 * i] = e[i].face0;
          d[4 * i + 1] = e[i].face1;
          d[4 * i + 2] = e[i].vertex0;
          d[4 * i + 3] = e[i].vertex1;
        }
        return out;
      });

  m.def("read_mesh", [](const std::string& path) {
    const MeshData data = without_gil([&] { return read_mesh(path); });
    return py::make_tuple(from_rows(data.positions), from_rows(data.triangles), from_std(data.triangle_polygon),
                          data.num_polygons);
  }, py::arg("path"), "Read OBJ/OFF/PLY: (positions, triangles, triangle_polygon, num_polygons)");
}

}  // namespace nfield::python
