// Binding of the operators area: nfield._native.FieldOperators (operators.hpp, per_face.hpp), principal
// curvature and alignment fields (curvature.hpp), singularity indices and ranges (singularities.hpp), the summary
// of a solution (field_summary.hpp).
#include <limits>
#include <string>

#include "binding_support.hpp"
#include "nfield/curvature.hpp"
#include "nfield/energy_rows.hpp"
#include "nfield/field_summary.hpp"
#include "nfield/operators.hpp"
#include "nfield/per_face.hpp"
#include "nfield/singularities.hpp"

namespace nfield::python {
namespace {

void require_order(int order) {
  if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4");
}

/// (vertices, indices N / n) of singular vertices, as two arrays.
py::tuple singularity_arrays(const FieldOperators& ops, const std::vector<VertexIndex>& singular) {
  std::vector<int> vertices;
  std::vector<double> indices;
  for (const auto& s : singular) {
    vertices.push_back(s.vertex);
    indices.push_back(static_cast<double>(s.numerator) / ops.n());
  }
  return py::make_tuple(from_std(vertices), from_std(indices));
}

/// A 1-D integer array as ints (the native functions check the range).
std::vector<int> int_list(const IndexArray& a, const char* what) {
  if (a.ndim() != 1) throw InputError(std::string(what) + " must be a 1-D integer array");
  std::vector<int> out(static_cast<std::size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    const long long x = a.data()[i];
    if (x < 0 || x > std::numeric_limits<int>::max())
      throw InputError(std::string(what) + " " + std::to_string(x) + " is out of range");
    out[static_cast<std::size_t>(i)] = static_cast<int>(x);
  }
  return out;
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
    return singularity_arrays(*ops, without_gil([&] { return singularity_indices(*ops, field); }));
  }, py::arg("ops"), py::arg("z"));

  m.def("singularity_indices_near", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& z,
                                       const IndexArray& faces) {
    const ComplexVector field = to_complex_vector(z, "field");
    const std::vector<int> list = int_list(faces, "face");
    return singularity_arrays(*ops, without_gil([&] { return singularity_indices_near(*ops, field, list); }));
  }, py::arg("ops"), py::arg("z"), py::arg("faces"),
        "(vertices, indices) of the singular vertices among the vertices of `faces`, in vertex order");

  m.def("field_summary", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& raw, int order, bool details) {
    const ComplexVector w = to_complex_vector(raw, "field");
    const FieldSummary s = without_gil([&] { return summarize_field(*ops, w, order, details); });
    const py::tuple singular = singularity_arrays(*ops, s.singularities);
    return py::make_tuple(from_complex(s.unit), from_rows(s.first_direction), s.energy, singular[0], singular[1]);
  }, py::arg("ops"), py::arg("raw"), py::arg("order"), py::arg("details") = true,
        "(unit field, first direction per face (F, 3), energy E_order of the unit field, singular vertices, their "
        "indices) of a raw solution per face; without details the energy is NaN and there are no singularities");

  m.def("field_summary_faces", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& raw,
                                  const IndexArray& faces) {
    const ComplexVector w = to_complex_vector(raw, "field");
    const std::vector<int> list = int_list(faces, "face");
    const FieldSummary s = without_gil([&] { return summarize_faces(*ops, w, list); });
    return py::make_tuple(from_complex(s.unit), from_rows(s.first_direction));
  }, py::arg("ops"), py::arg("raw"), py::arg("faces"),
        "(unit field, first direction (k, 3)) of a raw solution per face on `faces` only (a live local solve)");

  m.def("energy_change", [](std::shared_ptr<FieldOperators> ops, int order, const ComplexArray& before,
                            const ComplexArray& after, const IndexArray& faces) {
    const ComplexVector a = to_complex_vector(before, "before"), b = to_complex_vector(after, "after");
    const std::vector<int> list = int_list(faces, "face");
    return without_gil([&] { return energy_change(*ops, order, a, b, list); });
  }, py::arg("ops"), py::arg("order"), py::arg("before"), py::arg("after"), py::arg("faces"),
        "E_order(after) - E_order(before) for two fields per face that differ only on `faces` (energy_rows.hpp)");

  m.def("singularity_numerator_range", [](std::shared_ptr<FieldOperators> ops, int vertex) {
    return singularity_numerator_range(*ops, vertex);
  }, py::arg("ops"), py::arg("vertex"),
        "(lo, hi): the index numerators N (index N/n) the vertex's ring can carry; ValueError for other vertices");
}

}  // namespace nfield::python
