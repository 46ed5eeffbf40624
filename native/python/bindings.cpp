// pybind11 binding of the nfield native library: the module nfield._native.
// Only this file knows about Python. Heavy calls release the GIL; progress callbacks re-acquire it.
// Every C++ exception becomes a Python exception (ValueError / RuntimeError / nfield._native.Cancelled).
#include <pybind11/complex.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <climits>
#include <cmath>
#include <memory>
#include <optional>

#include "nfield/curvature.hpp"
#include "nfield/errors.hpp"
#include "nfield/mesh.hpp"
#include "nfield/memory_guard.hpp"
#include "nfield/mesh_io.hpp"
#include "nfield/mirror.hpp"
#include "nfield/operators.hpp"
#include "nfield/reduced_solver.hpp"
#include "nfield/spectral_basis.hpp"
#include "nfield/singularities.hpp"
#include "nfield/spectrum.hpp"
#include "nfield/spline_solver.hpp"
#include "nfield/streamlines.hpp"

namespace py = pybind11;
using namespace nfield;

void bind_remesh(py::module_& m);  // native/python/bind_remesh.cpp

namespace {

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IndexArray = py::array_t<long long, py::array::c_style | py::array::forcecast>;
using ComplexArray = py::array_t<std::complex<double>, py::array::c_style | py::array::forcecast>;

void require_shape(const py::array& a, py::ssize_t cols, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != cols)
    throw InputError(std::string(what) + " must be an array of shape (k, " + std::to_string(cols) + "), got " +
                     std::to_string(a.ndim()) + " dimension(s)" +
                     (a.ndim() >= 2 ? " with " + std::to_string(a.shape(1)) + " columns" : std::string()));
}

Positions to_positions(const DoubleArray& a) {
  require_shape(a, 3, "vertex positions");
  Positions P(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), P.data());
  return P;
}

Triangles to_triangles(const IndexArray& a, const char* what = "faces") {
  require_shape(a, 3, what);
  Triangles T(a.shape(0), 3);
  const long long* d = a.data();
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    if (d[i] < INT_MIN || d[i] > INT_MAX)
      throw InputError(std::string(what) + ": face " + std::to_string(i / 3) + " has vertex index " +
                       std::to_string(d[i]) + ", which is out of range");
    T.data()[i] = static_cast<int>(d[i]);
  }
  return T;
}

ComplexVector to_complex_vector(const ComplexArray& a, const char* what) {
  if (a.ndim() != 1) throw InputError(std::string(what) + " must be a 1-D complex array");
  return Eigen::Map<const ComplexVector>(a.data(), a.shape(0));
}

py::array_t<std::complex<double>> from_complex(const ComplexVector& v) {
  py::array_t<std::complex<double>> out(v.size());
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

py::array_t<double> from_vec3(const std::vector<Eigen::Vector3d>& v) {
  py::array_t<double> out({static_cast<py::ssize_t>(v.size()), py::ssize_t(3)});
  double* d = out.mutable_data();
  for (size_t i = 0; i < v.size(); ++i)
    for (int c = 0; c < 3; ++c) d[3 * i + c] = v[i][c];
  return out;
}

template <class Vec>
py::array_t<typename Vec::value_type> from_std(const Vec& v) {
  py::array_t<typename Vec::value_type> out(v.size());
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

py::array_t<double> from_eigen(const Eigen::VectorXd& v) {
  py::array_t<double> out(v.size());
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

/// A Python progress callable for the native code: called with the GIL held; False cancels. An exception
/// raised by the callable (KeyboardInterrupt too) cancels the computation and is then re-raised as itself
/// by run_with_progress instead of becoming Cancelled.
struct PythonProgress {
  ProgressCallback callback;
  std::shared_ptr<std::optional<py::error_already_set>> error = std::make_shared<std::optional<py::error_already_set>>();
};

PythonProgress wrap_progress(const py::object& callable) {
  PythonProgress p;
  if (callable.is_none()) return p;
  auto error = p.error;
  p.callback = [callable, error](double fraction) -> bool {
    py::gil_scoped_acquire gil;
    try {
      py::object r = callable(fraction);
      return r.is_none() || r.cast<bool>();
    } catch (py::error_already_set& e) {
      error->emplace(std::move(e));
      return false;
    } catch (const py::cast_error&) {
      error->emplace(py::error_already_set([] {
        PyErr_SetString(PyExc_TypeError, "progress callback must return a bool or None");
        return py::error_already_set();
      }()));
      return false;
    }
  };
  return p;
}

/// Runs `work` (which releases the GIL itself) and turns a cancel caused by an exception of the progress
/// callable back into that exception.
template <class Work>
auto run_with_progress(const PythonProgress& progress, Work&& work) -> decltype(work()) {
  try {
    return work();
  } catch (const Cancelled&) {
    if (progress.error->has_value()) {
      py::error_already_set e = std::move(**progress.error);
      progress.error->reset();
      throw e;
    }
    throw;
  }
}

py::dict report_to_dict(const MeshReport& r) {
  py::dict d;
  d["num_input_vertices"] = r.num_input_vertices;
  d["num_input_faces"] = r.num_input_faces;
  d["unused_vertices"] = r.unused_vertices;
  d["degenerate_faces"] = r.degenerate_faces;
  d["sliver_faces"] = r.sliver_faces;
  d["duplicate_faces"] = r.duplicate_faces;
  d["nonmanifold_edges"] = r.nonmanifold_edges;
  d["nonmanifold_vertices"] = r.nonmanifold_vertices;
  d["flipped_faces"] = r.flipped_faces;
  d["num_orientation_cuts"] = r.num_orientation_cuts;
  d["num_boundary_edges"] = r.num_boundary_edges;
  d["num_boundary_loops"] = r.num_boundary_loops;
  d["num_components"] = r.num_components;
  d["euler_characteristic"] = r.euler_characteristic;
  d["summary"] = r.summary();
  return d;
}

BasisPrecision parse_precision(const std::string& precision) {
  if (precision == "double") return BasisPrecision::Double;
  if (precision == "single") return BasisPrecision::Single;
  throw ParameterError("unknown basis precision '" + precision + "' (expected 'double' or 'single')");
}

const char* to_string(BasisPrecision p) { return p == BasisPrecision::Double ? "double" : "single"; }

/// Alignment argument of the solvers: None (no alignment) or one complex value per face.
ComplexVector optional_alignment(const py::object& alignment) {
  if (alignment.is_none()) return {};
  return to_complex_vector(alignment.cast<ComplexArray>(), "alignment");
}

SplineKind parse_kind(const std::string& kind) {
  if (kind == "direction") return SplineKind::Direction;
  if (kind == "vector") return SplineKind::Vector;
  throw ParameterError("unknown spline kind '" + kind + "' (expected 'direction' or 'vector')");
}

}  // namespace

void bind_guides(py::module_& m);  // bind_guides.cpp

PYBIND11_MODULE(_native, m) {
  m.doc() = "nfield native solver: n-symmetry direction field splines on triangle meshes";

  py::register_local_exception<Cancelled>(m, "Cancelled", PyExc_RuntimeError);
  py::register_local_exception<MemoryLimitError>(m, "InsufficientMemory", PyExc_MemoryError);
  // Module-local types and translators: two copies of this module (e.g. a development tree and an
  // installed Blender extension) can then live in one interpreter without clashing.
  // Registered after Cancelled and InsufficientMemory, so tried first; it leaves them to their translators.
  // std::bad_alloc (MemoryError) and other std::exception (RuntimeError) reach pybind11's default one.
  py::register_local_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const ParameterError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const ConstraintError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const SolverError& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });

  py::class_<TriangleMesh, std::shared_ptr<TriangleMesh>>(m, "Mesh", py::module_local(), "Validated, cleaned triangle mesh")
      .def(py::init([](const DoubleArray& positions, const IndexArray& faces) {
             Positions P = to_positions(positions);
             Triangles T = to_triangles(faces);
             py::gil_scoped_release release;
             return std::make_shared<TriangleMesh>(P, T);
           }),
           py::arg("positions"), py::arg("faces"))
      .def_property_readonly("num_vertices", &TriangleMesh::num_vertices)
      .def_property_readonly("num_faces", &TriangleMesh::num_faces)
      .def_property_readonly("num_active_faces", &TriangleMesh::num_active_faces)
      .def_property_readonly("positions", [](const TriangleMesh& m) {
        py::array_t<double> out({static_cast<py::ssize_t>(m.num_vertices()), py::ssize_t(3)});
        std::copy(m.positions().data(), m.positions().data() + m.positions().size(), out.mutable_data());
        return out;
      })
      .def_property_readonly("faces", [](const TriangleMesh& m) {
        py::array_t<int> out({static_cast<py::ssize_t>(m.num_faces()), py::ssize_t(3)});
        std::copy(m.faces().data(), m.faces().data() + m.faces().size(), out.mutable_data());
        return out;
      })
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
        if (v < 0 || v >= m.num_vertices()) throw InputError("vertex " + std::to_string(v) + " is out of range");
        return m.vertex_is_interior(v);
      })
      .def("angle_defect", [](const TriangleMesh& m, int v) {
        if (v < 0 || v >= m.num_vertices()) throw InputError("vertex " + std::to_string(v) + " is out of range");
        return m.angle_defect(v);
      })
      .def("vertex_ring_faces", [](const TriangleMesh& m, int v) {
        if (v < 0 || v >= m.num_vertices()) throw InputError("vertex " + std::to_string(v) + " is out of range");
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
    MeshData data;
    {
      py::gil_scoped_release release;
      data = read_mesh(path);
    }
    py::array_t<double> P({static_cast<py::ssize_t>(data.positions.rows()), py::ssize_t(3)});
    std::copy(data.positions.data(), data.positions.data() + data.positions.size(), P.mutable_data());
    py::array_t<int> T({static_cast<py::ssize_t>(data.triangles.rows()), py::ssize_t(3)});
    std::copy(data.triangles.data(), data.triangles.data() + data.triangles.size(), T.mutable_data());
    return py::make_tuple(P, T, from_std(data.triangle_polygon), data.num_polygons);
  }, py::arg("path"), "Read OBJ/OFF/PLY: (positions, triangles, triangle_polygon, num_polygons)");

  py::class_<FieldOperators, std::shared_ptr<FieldOperators>>(m, "FieldOperators", py::module_local(),
                                                              "Frames, n-connection and energies of a mesh")
      .def(py::init([](std::shared_ptr<TriangleMesh> mesh, int n, const std::string& weights) {
             const EdgeWeights w = parse_edge_weights(weights);
             py::gil_scoped_release release;
             return std::make_shared<FieldOperators>(mesh, n, w);
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
      .def_property_readonly("mass", [](const FieldOperators& o) {
        Eigen::VectorXd a = Eigen::VectorXd::Zero(o.mesh().num_faces());
        for (int u = 0; u < o.num_unknowns(); ++u) a[o.face_of_unknown(u)] = o.mass()[u];
        return from_eigen(a);
      })
      .def_property_readonly("connection", [](const FieldOperators& o) {
        ComplexVector r(o.mesh().dual_edges().size());
        for (Eigen::Index e = 0; e < r.size(); ++e) r[e] = o.transport(static_cast<int>(e));
        return from_complex(r);
      })
      .def_property_readonly("weights_per_edge", [](const FieldOperators& o) {
        Eigen::VectorXd w(o.mesh().dual_edges().size());
        for (Eigen::Index e = 0; e < w.size(); ++e) w[e] = o.edge_weight(static_cast<int>(e));
        return from_eigen(w);
      })
      .def("energy_matrix", [](const FieldOperators& o, int order) {
        ComplexSparse E;
        {
          py::gil_scoped_release release;
          E = o.energy_matrix(order);
        }
        std::vector<long long> rows, cols;
        std::vector<std::complex<double>> vals;
        for (int k = 0; k < E.outerSize(); ++k)
          for (ComplexSparse::InnerIterator it(E, k); it; ++it) {
            rows.push_back(o.face_of_unknown(static_cast<int>(it.row())));
            cols.push_back(o.face_of_unknown(static_cast<int>(it.col())));
            vals.push_back(it.value());
          }
        return py::make_tuple(from_std(rows), from_std(cols), from_std(vals));
      }, py::arg("order"), "COO triplets (rows, cols, values) of S (M^-1 S)^(order-1), in face indices")
      .def("energy", [](const FieldOperators& o, const ComplexArray& z, int order) {
        if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4");
        return o.energy(o.to_unknowns(to_complex_vector(z, "field")), order);
      }, py::arg("z"), py::arg("order"))
      .def("tangent_to_representation", [](const FieldOperators& o, const IndexArray& faces, const DoubleArray& vectors) {
        if (faces.ndim() != 1) throw InputError("faces must be a 1-D integer array");
        require_shape(vectors, 3, "vectors");
        if (vectors.shape(0) != faces.shape(0)) throw InputError("faces and vectors must have the same length");
        ComplexVector out(faces.shape(0));
        for (py::ssize_t i = 0; i < faces.shape(0); ++i) {
          const long long f = faces.data()[i];
          if (f < 0 || f >= o.mesh().num_faces())
            throw ConstraintError("face " + std::to_string(f) + " is out of range (mesh has " +
                                  std::to_string(o.mesh().num_faces()) + " faces)");
          if (!o.mesh().face_active(static_cast<int>(f)))
            throw ConstraintError("face " + std::to_string(f) + " is degenerate and excluded from the field");
          const Eigen::Vector3d v(vectors.data()[3 * i], vectors.data()[3 * i + 1], vectors.data()[3 * i + 2]);
          if (!v.allFinite()) throw ConstraintError("vector on face " + std::to_string(f) + " is not finite");
          out[i] = to_representation(o.frames().to_tangent(static_cast<int>(f), v), o.n());
        }
        return from_complex(out);
      }, py::arg("faces"), py::arg("vectors"))
      .def("representation_to_directions", [](const FieldOperators& o, const ComplexArray& z) {
        const ComplexVector v = to_complex_vector(z, "field");
        const int F = o.mesh().num_faces();
        if (v.size() != F) throw InputError("field must have one value per face (" + std::to_string(F) + ")");
        const int n = o.n();
        py::array_t<double> out({static_cast<py::ssize_t>(F), static_cast<py::ssize_t>(n), py::ssize_t(3)});
        double* d = out.mutable_data();
        std::fill(d, d + out.size(), 0.0);
        for (int f = 0; f < F; ++f) {
          if (!o.mesh().face_active(f) || !(std::abs(v[f]) > 0) || !std::isfinite(std::abs(v[f]))) continue;
          const double a = std::arg(v[f]) / n;
          for (int k = 0; k < n; ++k) {
            const Eigen::Vector3d t = o.frames().to_3d(f, std::polar(1.0, a + 2 * M_PI * k / n));
            for (int c = 0; c < 3; ++c) d[(f * n + k) * 3 + c] = t[c];
          }
        }
        return out;
      }, py::arg("z"))
      .def("ring_holonomy", [](const FieldOperators& o, int v) {
        if (v < 0 || v >= o.mesh().num_vertices() || !o.mesh().vertex_is_interior(v))
          throw InputError("vertex " + std::to_string(v) + " is not an interior vertex");
        return ring_holonomy(o, v);
      }, py::arg("vertex"));

  m.def("eigen", [](std::shared_ptr<FieldOperators> ops, int k, const py::object& progress) {
    const PythonProgress cb = wrap_progress(progress);
    const Eigenpairs pairs = run_with_progress(cb, [&] {
      py::gil_scoped_release release;
      return lowest_eigenpairs(*ops, k, cb.callback);
    });
    const int F = ops->mesh().num_faces();
    py::array_t<std::complex<double>> vecs({static_cast<py::ssize_t>(F), static_cast<py::ssize_t>(k)});
    auto* d = vecs.mutable_data();
    std::fill(d, d + vecs.size(), std::complex<double>(0, 0));
    for (int u = 0; u < ops->num_unknowns(); ++u)
      for (int c = 0; c < k; ++c) d[ops->face_of_unknown(u) * k + c] = pairs.vectors(u, c);
    return py::make_tuple(from_eigen(pairs.values), vecs);
  }, py::arg("ops"), py::arg("k"), py::arg("progress") = py::none(),
        "Lowest k eigenpairs of S z = lambda M z (complex form, ascending, M-orthonormal)");

  m.def("smoothest_field", [](std::shared_ptr<FieldOperators> ops) {
    ComplexVector z;
    {
      py::gil_scoped_release release;
      z = smoothest_field(*ops);
    }
    return from_complex(z);
  }, py::arg("ops"));

  m.def("principal_curvature", [](std::shared_ptr<TriangleMesh> mesh) {
    PrincipalCurvature pc;
    {
      py::gil_scoped_release release;
      TangentFrames frames(*mesh);
      pc = principal_curvature(*mesh, frames);
    }
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
    ComplexVector z;
    {
      py::gil_scoped_release release;
      z = curvature_alignment(*ops, kind == "curvature-max");
    }
    return from_complex(z);
  }, py::arg("ops"), py::arg("kind"));

  m.def("singularity_indices", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& z) {
    const auto idx = singularity_indices(*ops, to_complex_vector(z, "field"));
    std::vector<int> v;
    std::vector<double> x;
    for (const auto& s : idx) {
      v.push_back(s.vertex);
      x.push_back(static_cast<double>(s.numerator) / ops->n());
    }
    return py::make_tuple(from_std(v), from_std(x));
  }, py::arg("ops"), py::arg("z"));

  m.def("singularity_numerator_range", [](std::shared_ptr<FieldOperators> ops, int vertex) {
    return singularity_numerator_range(*ops, vertex);
  }, py::arg("ops"), py::arg("vertex"),
        "(lo, hi): the index numerators N (index N/n) the vertex's ring can carry; ValueError for other vertices");

  m.def("strength_to_lambda", [](std::shared_ptr<FieldOperators> ops, int order, double strength) {
    if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4");
    return strength_to_lambda(*ops, order, strength);
  }, py::arg("ops"), py::arg("order"), py::arg("strength"));

  py::class_<ExactSolver>(m, "ExactSolver", py::module_local(), "Exact n-field spline solver with cached factorization")
      .def(py::init([](std::shared_ptr<FieldOperators> ops, int order, double strength, const py::object& alignment,
                       const std::string& kind, double lambda_override, const py::object& progress,
                       const py::object& frozen_faces, const py::object& frozen_values, const py::object& anchor_faces,
                       bool cache_columns, const py::object& alignment_weight) {
             const ComplexVector a = optional_alignment(alignment);
             const SplineKind k = parse_kind(kind);
             const PythonProgress cb = wrap_progress(progress);
             std::vector<std::pair<int, Complex>> frozen;
             if (!frozen_faces.is_none()) {
               const IndexArray faces = frozen_faces.cast<IndexArray>();
               const ComplexArray values = frozen_values.cast<ComplexArray>();
               if (faces.ndim() != 1 || values.ndim() != 1 || faces.shape(0) != values.shape(0))
                 throw InputError("frozen_faces and frozen_values must be 1-D arrays of equal length");
               for (py::ssize_t i = 0; i < faces.shape(0); ++i) {
                 const long long f = faces.data()[i];
                 if (f < 0 || f >= ops->mesh().num_faces())
                   throw ConstraintError("frozen face " + std::to_string(f) + " is out of range");
                 frozen.emplace_back(static_cast<int>(f), values.data()[i]);
               }
             }
             std::vector<int> anchors;
             if (!anchor_faces.is_none()) {
               const IndexArray faces = anchor_faces.cast<IndexArray>();
               if (faces.ndim() != 1) throw InputError("anchor_faces must be a 1-D array of face indices");
               for (py::ssize_t i = 0; i < faces.shape(0); ++i) {
                 const long long f = faces.data()[i];
                 if (f < 0 || f >= ops->mesh().num_faces())
                   throw ConstraintError("anchor face " + std::to_string(f) + " is out of range");
                 anchors.push_back(static_cast<int>(f));
               }
             }
             Eigen::VectorXd weight;
             if (!alignment_weight.is_none()) {
               const DoubleArray w = alignment_weight.cast<DoubleArray>();
               if (w.ndim() != 1) throw InputError("alignment_weight must be a 1-D array (one weight per face)");
               weight = Eigen::Map<const Eigen::VectorXd>(w.data(), w.shape(0));
             }
             return run_with_progress(cb, [&] {
               py::gil_scoped_release release;
               return new ExactSolver(ops, order, strength, a, k, lambda_override, cb.callback, frozen, anchors,
                                      cache_columns, weight);
             });
           }),
           py::arg("ops"), py::arg("order") = 2, py::arg("strength") = 1.0, py::arg("alignment") = py::none(),
           py::arg("kind") = "direction", py::arg("lambda_override") = std::numeric_limits<double>::quiet_NaN(),
           py::arg("progress") = py::none(), py::arg("frozen_faces") = py::none(),
           py::arg("frozen_values") = py::none(), py::arg("anchor_faces") = py::none(),
           py::arg("cache_columns") = true, py::arg("alignment_weight") = py::none(),
           "Factor V = E_order - lambda M_W over the faces that are neither frozen (they keep their values) nor "
           "anchors (faces whose vector constraints are substituted); W the per-face alignment weight (1 by default); "
           "cache_columns=False: a one-shot solver")
      .def("set_alignment", [](ExactSolver& s, const py::object& alignment) {
        const ComplexVector a = optional_alignment(alignment);
        py::gil_scoped_release release;
        s.set_alignment(a);
      }, py::arg("alignment"), "New guide target values (W g per face): right-hand side only, no refactorization")
      .def("set_symmetry", [](ExactSolver& s, const py::object& mirror) {
        std::shared_ptr<const MirrorMap> m;
        if (!mirror.is_none()) m = mirror.cast<std::shared_ptr<MirrorMap>>();
        py::gil_scoped_release release;
        s.set_symmetry(m);
      }, py::arg("mirror"), "Solve on the mirror-symmetric fields of a MirrorMap (None: no symmetry)")
      .def_property_readonly("symmetric", &ExactSolver::symmetric)
      .def_property_readonly("symmetry_corrections", &ExactSolver::symmetry_corrections)
      .def("set_direction_constraint", &ExactSolver::set_direction_constraint, py::arg("face"), py::arg("d"))
      .def("set_vector_constraint", &ExactSolver::set_vector_constraint, py::arg("face"), py::arg("value"))
      .def("remove_constraint", &ExactSolver::remove_constraint, py::arg("face"))
      .def("set_singularity", &ExactSolver::set_singularity, py::arg("vertex"), py::arg("numerator"))
      .def("remove_singularity", &ExactSolver::remove_singularity, py::arg("vertex"))
      .def("clear_constraints", &ExactSolver::clear_constraints)
      .def("solve", [](ExactSolver& s) {
        ComplexVector w;
        {
          py::gil_scoped_release release;
          w = s.solve();
        }
        return from_complex(w);
      })
      .def_property_readonly("lambda_", &ExactSolver::lambda)
      .def_property_readonly("order", &ExactSolver::order)
      .def_property_readonly("sign_fixed_faces", &ExactSolver::sign_fixed_faces)
      .def_property_readonly("num_constraints", [](const ExactSolver& s) { return s.constraints().size(); })
      .def_property_readonly("num_cached_columns", &ExactSolver::num_cached_columns)
      .def_property_readonly("num_unknowns", &ExactSolver::num_unknowns)
      .def_property_readonly("num_factorizations", &ExactSolver::num_factorizations)
      .def_property_readonly("condition_estimate", &ExactSolver::condition_estimate)
      .def_property_readonly("anchor_faces", [](const ExactSolver& s) { return from_std(s.anchor_faces()); })
      .def("needs_refactorization", &ExactSolver::needs_refactorization, py::arg("vector_faces"),
           "Whether a solve with vector constraints on exactly these faces would refactor (stale anchors)")
      .def("face_frozen", &ExactSolver::face_frozen, py::arg("face"));

  // ---- spectral reduction (paper section 8): spectral_basis.hpp, reduced_solver.hpp ----
  py::class_<SpectralBasis, std::shared_ptr<SpectralBasis>>(
      m, "SpectralBasis", py::module_local(),
      "The first k eigenpairs of S z = lambda M z (M-orthonormal), for reduced solves and low-pass filtering")
      .def_static("compute", [](std::shared_ptr<FieldOperators> ops, int k, const std::string& precision,
                                const py::object& progress, double tolerance, int slice_size) {
        SpectralBasisOptions options;
        options.precision = parse_precision(precision);
        if (!(tolerance > 0 && tolerance < 1e-2)) throw ParameterError("tolerance must lie in (0, 1e-2)");
        options.tolerance = tolerance;
        if (slice_size < 0) throw ParameterError("slice_size must be >= 0 (0: automatic)");
        options.slice_size = slice_size;
        const PythonProgress cb = wrap_progress(progress);
        return run_with_progress(cb, [&] {
          py::gil_scoped_release release;
          return std::make_shared<SpectralBasis>(SpectralBasis::compute(*ops, k, options, cb.callback));
        });
      }, py::arg("ops"), py::arg("k"), py::arg("precision") = "double", py::arg("progress") = py::none(),
         py::arg("tolerance") = 1e-10, py::arg("slice_size") = 0,
         "Compute the basis (expensive; GIL released; progress(fraction) returning False cancels)")
      .def_static("load", [](const std::string& path, std::shared_ptr<FieldOperators> ops, int k,
                             const py::object& precision) {
        const int p = precision.is_none() ? -1 : static_cast<int>(parse_precision(precision.cast<std::string>()));
        py::gil_scoped_release release;
        return std::make_shared<SpectralBasis>(SpectralBasis::load(path, *ops, k, p));
      }, py::arg("path"), py::arg("ops"), py::arg("k") = 0, py::arg("precision") = py::none(),
         "Read a basis saved for these operators; ValueError if missing, corrupt or stale")
      .def("save", [](const SpectralBasis& b, const std::string& path) {
        py::gil_scoped_release release;
        b.save(path);
      }, py::arg("path"))
      .def_property_readonly("size", &SpectralBasis::size)
      .def_property_readonly("num_unknowns", &SpectralBasis::num_unknowns)
      .def_property_readonly("precision", [](const SpectralBasis& b) { return to_string(b.precision()); })
      .def_property_readonly("memory_bytes", &SpectralBasis::memory_bytes)
      .def_property_readonly("mesh_hash", &SpectralBasis::mesh_hash)
      .def_property_readonly("n", &SpectralBasis::n)
      .def_property_readonly("weights", [](const SpectralBasis& b) { return to_string(b.weights()); })
      .def_property_readonly("values", [](const SpectralBasis& b) { return from_eigen(b.values()); })
      .def("vectors", [](const SpectralBasis& b, std::shared_ptr<FieldOperators> ops) {
        if (b.num_unknowns() != ops->num_unknowns()) throw ParameterError("basis and operators do not match");
        const int F = ops->mesh().num_faces(), k = b.size();
        const Eigen::MatrixXcd U = b.vectors();
        py::array_t<std::complex<double>> out({static_cast<py::ssize_t>(F), static_cast<py::ssize_t>(k)});
        auto* d = out.mutable_data();
        std::fill(d, d + out.size(), std::complex<double>(0, 0));
        for (int u = 0; u < U.rows(); ++u)
          for (int c = 0; c < k; ++c) d[static_cast<py::ssize_t>(ops->face_of_unknown(u)) * k + c] = U(u, c);
        return out;
      }, py::arg("ops"), "The eigenvectors per face (F, k), zero rows on excluded faces")
      .def("truncated", &SpectralBasis::truncated, py::arg("k"))
      .def("with_precision", [](const SpectralBasis& b, const std::string& precision) {
        return b.with_precision(parse_precision(precision));
      }, py::arg("precision"));

  m.def("estimate_basis_bytes", [](std::shared_ptr<FieldOperators> ops, int k, const std::string& precision) {
    SpectralBasisOptions options;
    options.precision = parse_precision(precision);
    py::gil_scoped_release release;
    return estimate_basis_bytes(*ops, k, options);
  }, py::arg("ops"), py::arg("k"), py::arg("precision") = "double",
        "Estimated peak memory (bytes) of computing a basis of k eigenfields");
  m.def("available_memory_bytes", &available_memory_bytes,
        "Bytes the memory guard considers available (MemAvailable, cgroup limit, NFIELD_MEMORY_LIMIT_MB); 0 if unknown");

  m.def("basis_cache_key", [](std::shared_ptr<FieldOperators> ops, int k, const std::string& precision) {
    return cache_key(*ops, k, parse_precision(precision));
  }, py::arg("ops"), py::arg("k"), py::arg("precision") = "double",
        "File-name-safe key of a basis (mesh content hash, n, weights, size, k, precision)");

  m.def("low_pass", [](std::shared_ptr<FieldOperators> ops, std::shared_ptr<SpectralBasis> basis,
                       const ComplexArray& field) {
    const ComplexVector z = to_complex_vector(field, "field");
    ComplexVector out;
    {
      py::gil_scoped_release release;
      out = low_pass(*ops, *basis, z);
    }
    return from_complex(out);
  }, py::arg("ops"), py::arg("basis"), py::arg("field"),
        "U U^H M field: the M-orthogonal projection of a per-face field onto the basis");

  py::class_<ReducedSolver>(m, "ReducedSolver", py::module_local(),
                            "Reduced n-field spline solver in a spectral basis (eqs. 16-18)")
      .def(py::init([](std::shared_ptr<FieldOperators> ops, std::shared_ptr<SpectralBasis> basis, int order,
                       double strength, const py::object& alignment, const std::string& kind,
                       double lambda_override) {
             const ComplexVector a = optional_alignment(alignment);
             const SplineKind k = parse_kind(kind);
             py::gil_scoped_release release;
             return new ReducedSolver(ops, basis, order, strength, a, k, lambda_override);
           }),
           py::arg("ops"), py::arg("basis"), py::arg("order") = 2, py::arg("strength") = 1.0,
           py::arg("alignment") = py::none(), py::arg("kind") = "direction",
           py::arg("lambda_override") = std::numeric_limits<double>::quiet_NaN())
      .def("set_strength", &ReducedSolver::set_strength, py::arg("strength"),
           "Change the alignment strength live (no factorization: O(k))")
      .def("set_lambda", &ReducedSolver::set_lambda, py::arg("lambda_"))
      .def("set_alignment", [](ReducedSolver& s, const py::object& alignment) {
        const ComplexVector a = optional_alignment(alignment);
        py::gil_scoped_release release;
        s.set_alignment(a);
      }, py::arg("alignment"))
      .def("set_direction_constraint", &ReducedSolver::set_direction_constraint, py::arg("face"), py::arg("d"))
      .def("set_vector_constraint", &ReducedSolver::set_vector_constraint, py::arg("face"), py::arg("value"))
      .def("remove_constraint", &ReducedSolver::remove_constraint, py::arg("face"))
      .def("set_singularity", &ReducedSolver::set_singularity, py::arg("vertex"), py::arg("numerator"))
      .def("remove_singularity", &ReducedSolver::remove_singularity, py::arg("vertex"))
      .def("clear_constraints", &ReducedSolver::clear_constraints)
      .def("solve_coefficients", [](ReducedSolver& s) {
        ComplexVector x;
        {
          py::gil_scoped_release release;
          x = s.solve_coefficients();
        }
        return from_complex(x);
      }, "The reduced solution x (k): the field is U x (no reconstruction)")
      .def("solve", [](ReducedSolver& s) {
        ComplexVector w;
        {
          py::gil_scoped_release release;
          w = s.solve();
        }
        return from_complex(w);
      }, "The field per face (U x, constrained faces snapped)")
      .def("reconstruct", [](const ReducedSolver& s, const ComplexArray& x) {
        const ComplexVector c = to_complex_vector(x, "coefficients");
        if (c.size() != s.size())
          throw InputError("coefficients must have size k = " + std::to_string(s.size()) + ", got " +
                           std::to_string(c.size()));
        ComplexVector w;
        {
          py::gil_scoped_release release;
          w = s.reconstruct(c);
        }
        return from_complex(w);
      }, py::arg("x"))
      .def_property_readonly("lambda_", &ReducedSolver::lambda)
      .def_property_readonly("order", &ReducedSolver::order)
      .def_property_readonly("size", &ReducedSolver::size)
      .def_property_readonly("sign_fixed_faces", &ReducedSolver::sign_fixed_faces)
      .def_property_readonly("constraint_residual", &ReducedSolver::constraint_residual)
      .def_property_readonly("uncovered_components", &ReducedSolver::uncovered_components)
      .def_property_readonly("num_constraints", [](const ReducedSolver& s) { return s.constraints().size(); });

  // ---- BEGIN streamlines (hatching strokes; native/src/streamlines.cpp) ----
  m.def("trace_streamlines", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& z, double separation,
                                int family, bool cross_hatch, double max_length, double min_length,
                                unsigned long long seed, const py::object& density, bool density_per_vertex,
                                double test_ratio, double step_ratio, double max_turn, bool stop_at_singularities,
                                double min_density, long long max_total_points) {
    const ComplexVector field = to_complex_vector(z, "field");
    StreamlineParams p;
    p.separation = separation;
    p.family = family;
    p.cross_hatch = cross_hatch;
    p.max_length = max_length;
    p.min_length = min_length;
    p.seed = seed;
    p.test_ratio = test_ratio;
    p.step_ratio = step_ratio;
    p.seed_ratio = std::max(0.9, test_ratio);
    p.max_turn = max_turn;
    p.stop_at_singularities = stop_at_singularities;
    p.min_density = min_density;
    p.max_total_points = max_total_points;
    if (!density.is_none()) {
      const DoubleArray d = density.cast<DoubleArray>();
      if (d.ndim() != 1) throw InputError("density must be a 1-D array");
      p.density.assign(d.data(), d.data() + d.shape(0));
      p.density_per_vertex = density_per_vertex;
    }
    Streamlines r;
    {
      py::gil_scoped_release release;
      r = trace_streamlines(*ops, field, p);
    }
    py::list points, faces;
    std::vector<int> families;
    std::vector<double> lengths;
    for (const Stroke& s : r.strokes) {
      points.append(from_vec3(s.points));
      faces.append(from_std(s.faces));
      families.push_back(s.family);
      lengths.push_back(s.length);
    }
    py::dict stats;
    stats["num_points"] = r.stats.num_points;
    stats["num_strokes"] = r.stats.num_strokes;
    stats["num_discarded"] = r.stats.num_discarded;
    stats["num_candidates"] = r.stats.num_candidates;
    stats["num_blocked_faces"] = r.stats.num_blocked_faces;
    stats["num_singularities"] = r.stats.num_singularities;
    stats["truncated"] = r.stats.truncated;
    stats["coverage"] = r.stats.coverage;
    return py::make_tuple(points, faces, from_std(families), from_std(lengths), stats);
  }, py::arg("ops"), py::arg("z"), py::arg("separation"), py::arg("family") = 0, py::arg("cross_hatch") = false,
        py::arg("max_length") = std::numeric_limits<double>::infinity(), py::arg("min_length") = 0.0,
        py::arg("seed") = 0ULL, py::arg("density") = py::none(), py::arg("density_per_vertex") = true,
        py::arg("test_ratio") = 0.5, py::arg("step_ratio") = 0.2, py::arg("max_turn") = M_PI / 4,
        py::arg("stop_at_singularities") = true, py::arg("min_density") = 0.1,
        py::arg("max_total_points") = 5000000LL,
        "Evenly spaced streamlines of a per-face field (see streamlines.hpp): "
        "(points list of (k,3), faces list of (k,), families, lengths, stats dict)");
  // ---- END streamlines ----

  bind_guides(m);
  bind_remesh(m);
}
