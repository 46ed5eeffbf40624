// Binding of the operators area: nfield._native.FieldOperators (operators.hpp, per_face.hpp), principal
// curvature and alignment fields (curvature.hpp), singularity indices and ranges (singularities.hpp), the summary
// of a solution (field_summary.hpp).
#include <string>

#include "binding_support.hpp"
#include "nfield/curvature.hpp"
#include "nfield/field_summary.hpp"
#include "nfield/operators.hpp"
#include "nfield/per_face.hpp"
#include "nfield/singularities.hpp"

namespace nfield::python {
namespace {

void require_order(int order) {
  if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4");
}

}  // namespace

void bind_operators(py::module_& m) {
  py::class_<FieldOperators, std::shared_ptr<FieldOperators>>(m, "FieldOperators", py::module_local(),
                                                              "Frames, n-connection and energies of a mesh")
      .def(py::init([](std::shared_ptr<TriangleMesh> mesh, int n, const std::string& weights) {
             const EdgeWeights w = parse_edge_weights(weights);
             return without_gil([&] { return std::make_shared<FieldOperators>(mesh, n, w); });
           }),
           py::arg("mesh"), py::arg("n"), py::arg("weights") = "geometric")
      .def_property_readonly("n", &FieldOperators::n)
      .def_property_readonly("weights", [](const FieldOperators& o) { return to_string(o.weights()); })
      .def_property_readonly("mesh", [](const FieldOperators& o) {
        return std::const_pointer_cast<TriangleMesh>(o.mesh_ptr());
      })
      .def_property_readonly("frames", [](const FieldOperators& o) {
        const int F = o.mesh().num_faces();
        py::array_t<double> out({static_cast<py::ssize_t>(F), py::ssize_t(2), py::ssize_t(3)});
        double* d = out.mutable_data();
        for (int f = 0; f < F; ++f)
          for (int c = 0; c < 3; ++c) {
            d[6 * f + c] = o.frames().x_axis(f)[c];
            d[6 * f + 3 + c] = o.frames().y_axis(f)[c];
          }
        return out;
      })
      .def_property_readonly("mass", [](const FieldOperators& o) { return from_eigen(mass_per_face(o)); })
      .def_property_readonly("connection", [](const FieldOperators& o) { return from_complex(transport_per_edge(o)); })
      .def_property_readonly("weights_per_edge", [](const FieldOperators& o) { return from_eigen(weight_per_edge(o)); })
      .def("energy_matrix", [](const FieldOperators& o, int order) {
        const FaceTriplets t = without_gil([&] { return to_face_triplets(o, o.energy_matrix(order)); });
        return py::make_tuple(from_std(t.rows), from_std(t.cols), from_std(t.values));
      }, py::arg("order"), "COO triplets (rows, cols, values) of S (M^-1 S)^(order-1), in face indices")
      .def("energy", [](const FieldOperators& o, const ComplexArray& z, int order) {
        require_order(order);
        return o.energy(o.to_unknowns(to_complex_vector(z, "field")), order);
      }, py::arg("z"), py::arg("order"))
      .def("tangent_to_representation", [](const FieldOperators& o, const IndexArray& faces, const DoubleArray& vectors) {
        if (faces.ndim() != 1) throw InputError("faces must be a 1-D integer array");
        require_shape(vectors, 3, "vectors");
        const Eigen::Map<const Eigen::Matrix<long long, Eigen::Dynamic, 1>> f(faces.data(), faces.shape(0));
        const Eigen::Map<const Vectors3> v(vectors.data(), vectors.shape(0), 3);
        return from_complex(tangent_vectors_to_representation(o, f, v));
      }, py::arg("faces"), py::arg("vectors"))
      .def("representation_to_directions", [](const FieldOperators& o, const ComplexArray& z) {
        const Vectors3 d = directions_per_face(o, to_complex_vector(z, "field"));
        py::array_t<double> out({static_cast<py::ssize_t>(o.mesh().num_faces()), static_cast<py::ssize_t>(o.n()),
                                 py::ssize_t(3)});
        std::copy(d.data(), d.data() + d.size(), out.mutable_data());
        return out;
      }, py::arg("z"))
      .def("ring_holonomy", [](const FieldOperators& o, int v) {
        if (v < 0 || v >= o.mesh().num_vertices() || !o.mesh().vertex_is_interior(v))
          throw InputError("vertex " + std::to_string(v) + " is not an interior vertex");
        return ring_holonomy(o, v);
      }, py::arg("vertex"));

  m.def("principal_curvature", [](std::shared_ptr<TriangleMesh> mesh) {
    const PrincipalCurvature pc = without_gil([&] {
      TangentFrames frames(*mesh);
      return principal_curvature(*mesh, frames);
    });
    py::dict d;
    d["kmax"] = from_eigen(pc.kmax);
    d["kmin"] = from_eigen(pc.kmin);
    d["dir_max"] = from_vec3(pc.dir_max);
    d["dir_min"] = from_vec3(pc.dir_min);
    return d;
  }, py::arg("mesh"));

  m.def("alignment_field", [](std::shared_ptr<FieldOperators> ops, const std::string& kind) {
    if (kind != "curvature-max" && kind != "curvature-min")
      throw ParameterError("unknown alignment '" + kind + "' (expected 'curvature-max' or 'curvature-min')");
    return from_complex(without_gil([&] { return curvature_alignment(*ops, kind == "curvature-max"); }));
  }, py::arg("ops"), py::arg("kind"));

  m.def("singularity_indices", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& z) {
    const ComplexVector field = to_complex_vector(z, "field");
    const auto idx = without_gil([&] { return singularity_indices(*ops, field); });
    std::vector<int> v;
    std::vector<double> x;
    for (const auto& s : idx) {
      v.push_back(s.vertex);
      x.push_back(static_cast<double>(s.numerator) / ops->n());
    }
    return py::make_tuple(from_std(v), from_std(x));
  }, py::arg("ops"), py::arg("z"));

  m.def("field_summary", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& raw, int order, bool details) {
    const ComplexVector w = to_complex_vector(raw, "field");
    const FieldSummary s = without_gil([&] { return summarize_field(*ops, w, order, details); });
    std::vector<int> vertices;
    std::vector<double> indices;
    for (const auto& v : s.singularities) {
      vertices.push_back(v.vertex);
      indices.push_back(static_cast<double>(v.numerator) / ops->n());
    }
    return py::make_tuple(from_complex(s.unit), from_rows(s.first_direction), s.energy, from_std(vertices),
                          from_std(indices));
  }, py::arg("ops"), py::arg("raw"), py::arg("order"), py::arg("details") = true,
        "(unit field, first direction per face (F, 3), energy E_order of the unit field, singular vertices, their "
        "indices) of a raw solution per face; without details the energy is NaN and there are no singularities");

  m.def("singularity_numerator_range", [](std::shared_ptr<FieldOperators> ops, int vertex) {
    return singularity_numerator_range(*ops, vertex);
  }, py::arg("ops"), py::arg("vertex"),
        "(lo, hi): the index numerators N (index N/n) the vertex's ring can carry; ValueError for other vertices");
}

}  // namespace nfield::python
