// pybind11 binding of guide authoring (features, curves, comb, mirror symmetry, cuts): part of the module
// nfield._native, registered by bind_guides() from the module definition in module.cpp. Native errors
// reach Python through the module's exception translators (ValueError / RuntimeError). Calls that walk
// the mesh release the GIL.
#include <pybind11/complex.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <climits>
#include <cmath>
#include <memory>

#include "binding_support.hpp"
#include "nfield/comb.hpp"
#include "nfield/curve_guide.hpp"
#include "nfield/energy_rows.hpp"
#include "nfield/errors.hpp"
#include "nfield/face_regions.hpp"
#include "nfield/features.hpp"
#include "nfield/guide_field.hpp"
#include "nfield/guide_geometry.hpp"
#include "nfield/mesh_cuts.hpp"
#include "nfield/mirror.hpp"

namespace nfield::python {
namespace {

std::vector<Eigen::Vector3d> to_points(const DoubleArray& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 3) throw InputError(std::string(what) + " must be an array of shape (k, 3)");
  std::vector<Eigen::Vector3d> out(static_cast<std::size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) out[i] = Eigen::Vector3d(a.at(i, 0), a.at(i, 1), a.at(i, 2));
  return out;
}

std::vector<std::array<int, 2>> to_pairs(const py::object& obj, const char* what) {
  std::vector<std::array<int, 2>> out;
  if (obj.is_none()) return out;
  const IndexArray a = obj.cast<IndexArray>();
  if (a.size() == 0) return out;
  if (a.ndim() != 2 || a.shape(1) != 2) throw InputError(std::string(what) + " must be an array of shape (k, 2) (vertex pairs)");
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    const long long u = a.at(i, 0), v = a.at(i, 1);
    if (u < 0 || v < 0 || u > INT_MAX || v > INT_MAX)
      throw InputError(std::string(what) + ": vertex index out of range in pair " + std::to_string(i));
    out.push_back({static_cast<int>(u), static_cast<int>(v)});
  }
  return out;
}

py::array_t<int> pairs_array(const std::vector<std::array<int, 2>>& pairs) {
  py::array_t<int> out({static_cast<py::ssize_t>(pairs.size()), py::ssize_t(2)});
  for (std::size_t i = 0; i < pairs.size(); ++i) out.mutable_at(i, 0) = pairs[i][0], out.mutable_at(i, 1) = pairs[i][1];
  return out;
}

template <class T>
py::array_t<T> vector_array(const std::vector<T>& v) {
  py::array_t<T> out(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

py::array_t<double> points_array(const std::vector<Eigen::Vector3d>& v) {
  py::array_t<double> out({static_cast<py::ssize_t>(v.size()), py::ssize_t(3)});
  for (std::size_t i = 0; i < v.size(); ++i)
    for (int c = 0; c < 3; ++c) out.mutable_at(i, c) = v[i][c];
  return out;
}

py::tuple layer_tuple(const GuideLayer& layer) {
  py::array_t<std::complex<double>> value(layer.value.size());
  std::copy(layer.value.data(), layer.value.data() + layer.value.size(), value.mutable_data());
  py::array_t<double> weight(layer.weight.size());
  std::copy(layer.weight.data(), layer.weight.data() + layer.weight.size(), weight.mutable_data());
  return py::make_tuple(value, weight);
}

py::tuple directions_tuple(const std::vector<HardDirection>& d) {
  std::vector<int> faces, sources;
  std::vector<std::complex<double>> dirs;
  for (const auto& h : d) faces.push_back(h.face), dirs.push_back(h.direction), sources.push_back(h.source);
  return py::make_tuple(vector_array(faces), vector_array(dirs), vector_array(sources));
}

void check_n(int n) {
  if (n < 1 || n > 64) throw ParameterError("symmetry n must be between 1 and 64, got " + std::to_string(n));
}

CombField to_comb(const GuideGeometry& g, const DoubleArray& directions, const DoubleArray& weights) {
  const int nf = g.mesh().num_faces();
  if (directions.ndim() != 2 || directions.shape(0) != nf || directions.shape(1) != 3)
    throw InputError("comb directions must have shape (" + std::to_string(nf) + ", 3) (one per face)");
  if (weights.ndim() != 1 || weights.shape(0) != nf)
    throw InputError("comb weights must have shape (" + std::to_string(nf) + ",) (one per face)");
  CombField field{to_points(directions, "comb directions"), Eigen::Map<const Eigen::VectorXd>(weights.data(), nf)};
  for (int f = 0; f < nf; ++f)
    if (!(field.weight[f] >= 0 && field.weight[f] <= 1) || !field.direction[f].allFinite())
      throw InputError("comb field at face " + std::to_string(f) + " is invalid (weights lie in [0, 1], directions are finite)");
  return field;
}

/// A comb stroke in progress with the geometry it walks on (kept alive as long as the stroke).
struct CombStrokeInProgress {
  std::shared_ptr<const GuideGeometry> geometry;
  CombStrokeState state;
};

}  // namespace

void bind_guides(py::module_& m) {
  py::class_<CombStrokeInProgress, std::shared_ptr<CombStrokeInProgress>>(
      m, "CombStrokeInProgress", py::module_local(),
      "A comb stroke taking its samples in batches (comb.hpp, CombStrokeState); GuideGeometry.begin_comb_stroke")
      .def("add", [](CombStrokeInProgress& s, const DoubleArray& points, const DoubleArray& stroke_directions) {
        const auto p = to_points(points, "stroke points"), d = to_points(stroke_directions, "stroke directions");
        std::vector<int> reached;
        {
          py::gil_scoped_release release;
          reached = s.state.add(s.geometry->frames(), s.geometry->tree(), p, d);
        }
        const CombField& field = s.state.field();
        std::vector<Eigen::Vector3d> dirs;
        py::array_t<double> w(static_cast<py::ssize_t>(reached.size()));
        for (std::size_t i = 0; i < reached.size(); ++i)
          dirs.push_back(field.direction[reached[i]]), w.mutable_at(i) = field.weight[reached[i]];
        return py::make_tuple(vector_array(reached), points_array(dirs), w);
      }, py::arg("points"), py::arg("stroke_directions"),
         "Adds samples: (faces they reached, sorted; the directions (k, 3) and weights (k,) there after the stroke so far)")
      .def_property_readonly("changed", [](const CombStrokeInProgress& s) { return vector_array(s.state.changed()); },
                             "every face the stroke changed so far, sorted");

  py::class_<FeatureSet, std::shared_ptr<FeatureSet>>(m, "FeatureSet", py::module_local(),
                                                      "Feature edges linked into chains (features.hpp)")
      .def_property_readonly("edge_ids", [](const FeatureSet& s) { return vector_array(s.edges); })
      .def_property_readonly("chains", [](const FeatureSet& s) {
        py::list out;
        for (const auto& c : s.chains) {
          py::dict d;
          d["vertices"] = vector_array(c.vertices);
          d["edges"] = vector_array(c.edges);
          d["closed"] = c.closed;
          out.append(d);
        }
        return out;
      })
      .def_property_readonly("corners", [](const FeatureSet& s) { return vector_array(s.corners); })
      .def_property_readonly("num_boundary", [](const FeatureSet& s) { return s.num_boundary; })
      .def_property_readonly("num_sharp", [](const FeatureSet& s) { return s.num_sharp; })
      .def_property_readonly("num_marked", [](const FeatureSet& s) { return s.num_marked; });

  py::class_<ProjectedCurve, std::shared_ptr<ProjectedCurve>>(m, "ProjectedCurve", py::module_local(),
                                                              "A polyline's samples on the surface (curve_guide.hpp)")
      .def_property_readonly("faces", [](const ProjectedCurve& c) { return vector_array(c.faces); })
      .def_property_readonly("points", [](const ProjectedCurve& c) { return points_array(c.points); })
      .def_property_readonly("tangents", [](const ProjectedCurve& c) { return points_array(c.tangents); })
      .def_property_readonly("num_samples", [](const ProjectedCurve& c) { return c.num_samples; })
      .def_property_readonly("num_missed", [](const ProjectedCurve& c) { return c.num_missed; })
      .def_property_readonly("max_distance", [](const ProjectedCurve& c) { return c.max_distance; });

  py::class_<GuideGeometry, std::shared_ptr<GuideGeometry>>(
      m, "GuideGeometry", py::module_local(), "Frames, edge table and closest-point tree of a mesh, for guides")
      .def(py::init([](std::shared_ptr<TriangleMesh> mesh) {
             py::gil_scoped_release release;
             return std::make_shared<GuideGeometry>(mesh);
           }),
           py::arg("mesh"))
      .def_property_readonly("num_edges", [](const GuideGeometry& g) { return g.edges().num_edges(); })
      .def_property_readonly("typical_edge_length", &GuideGeometry::typical_edge_length)
      .def("edges", [](const GuideGeometry& g) {
        std::vector<std::array<int, 2>> v(g.edges().num_edges());
        for (int e = 0; e < g.edges().num_edges(); ++e) v[e] = g.edges().vertices(e);
        return pairs_array(v);
      }, "(E, 2) vertex pairs of every edge of the usable faces, sorted")
      .def("edge_faces", [](const GuideGeometry& g, int e) {
        if (e < 0 || e >= g.edges().num_edges()) throw InputError("edge " + std::to_string(e) + " is out of range");
        std::vector<int> faces;
        for (int k = 0; k < g.edges().num_faces(e); ++k) faces.push_back(g.edges().face(e, k));
        return faces;
      }, py::arg("edge"))
      .def("dihedral_angles", [](const GuideGeometry& g) {
        std::vector<double> a(g.edges().num_edges());
        for (int e = 0; e < g.edges().num_edges(); ++e) a[e] = g.edges().dihedral_angle(g.mesh(), e);
        return vector_array(a);
      }, "bend angle (radians) per edge; -1 for boundary and non-manifold edges")
      .def("detect_features", [](const GuideGeometry& g, bool boundary, double sharp_angle, const py::object& edges,
                                 double corner_angle) {
        FeatureOptions o;
        o.boundary = boundary;
        o.sharp_angle = sharp_angle;
        o.edges = to_pairs(edges, "feature edges");
        o.corner_angle = corner_angle;
        py::gil_scoped_release release;
        return std::make_shared<FeatureSet>(detect_features(g.mesh(), g.edges(), o));
      }, py::arg("boundary") = true, py::arg("sharp_angle") = -1.0, py::arg("edges") = py::none(),
         py::arg("corner_angle") = 45.0)
      .def("feature_band", [](const GuideGeometry& g, const FeatureSet& s, int n, int width) {
        check_n(n);
        GuideLayer layer;
        {
          py::gil_scoped_release release;
          layer = feature_band_guide(g.mesh(), g.frames(), n, g.edges(), s, width);
        }
        return layer_tuple(layer);
      }, py::arg("features"), py::arg("n"), py::arg("width"), "(value complex (F,), weight (F,))")
      .def("feature_hard", [](const GuideGeometry& g, const FeatureSet& s, int n, int every) {
        check_n(n);
        return directions_tuple(feature_hard_directions(g.mesh(), g.frames(), n, g.edges(), s, every));
      }, py::arg("features"), py::arg("n"), py::arg("every") = 1, "(faces, unit representation vectors, chain ids)")
      .def("project_curve", [](const GuideGeometry& g, const DoubleArray& points, double spacing, double tolerance) {
        const auto p = to_points(points, "curve points");
        py::gil_scoped_release release;
        return std::make_shared<ProjectedCurve>(project_curve(g.tree(), p, spacing, tolerance));
      }, py::arg("points"), py::arg("spacing"), py::arg("tolerance"))
      .def("curve_band", [](const GuideGeometry& g, const std::vector<std::shared_ptr<ProjectedCurve>>& curves,
                            const std::vector<double>& widths, const std::vector<double>& weights, int n) {
        check_n(n);
        if (curves.size() != widths.size() || curves.size() != weights.size())
          throw InputError("curve_band needs one width and one weight per curve");
        GuideLayer layer;
        {
          py::gil_scoped_release release;
          GuideAccumulator acc(g.mesh().num_faces());
          for (std::size_t i = 0; i < curves.size(); ++i) add_curve_band(g.mesh(), g.frames(), n, *curves[i], widths[i], weights[i], acc);
          layer = acc.finish();
        }
        return layer_tuple(layer);
      }, py::arg("curves"), py::arg("widths"), py::arg("weights"), py::arg("n"),
         "Soft guide layer of several projected curves: (value complex (F,), weight (F,))")
      .def("curve_hard", [](const GuideGeometry& g, const ProjectedCurve& c, int n, int every, int source) {
        check_n(n);
        return directions_tuple(curve_hard_directions(g.frames(), n, c, every, source));
      }, py::arg("curve"), py::arg("n"), py::arg("every") = 1, py::arg("source") = 0)
      .def("comb_stroke", [](const GuideGeometry& g, const DoubleArray& directions, const DoubleArray& weights, int n,
                             const DoubleArray& points, const DoubleArray& stroke_directions, double radius,
                             const std::string& falloff, double strength) {
        check_n(n);
        CombField field = to_comb(g, directions, weights);
        CombStroke stroke{to_points(points, "stroke points"), to_points(stroke_directions, "stroke directions"), radius,
                          parse_falloff(falloff), strength};
        std::vector<int> changed;
        {
          py::gil_scoped_release release;
          changed = apply_comb_stroke(g.mesh(), g.frames(), g.tree(), n, stroke, field);
        }
        py::array_t<double> w(field.weight.size());
        std::copy(field.weight.data(), field.weight.data() + field.weight.size(), w.mutable_data());
        return py::make_tuple(points_array(field.direction), w, vector_array(changed));
      }, py::arg("directions"), py::arg("weights"), py::arg("n"), py::arg("points"), py::arg("stroke_directions"),
         py::arg("radius"), py::arg("falloff") = "smooth", py::arg("strength") = 1.0,
         "One comb stroke: (new directions (F,3), new weights (F,), changed faces)")
      .def("closest_faces", [](const GuideGeometry& g, const DoubleArray& points) {
        const auto p = to_points(points, "points");
        std::vector<int> faces(p.size());
        {
          py::gil_scoped_release release;
          for (std::size_t i = 0; i < p.size(); ++i) faces[i] = g.tree().closest(p[i]).face;
        }
        return vector_array(faces);
      }, py::arg("points"), "The face nearest to each point (closest point on the surface; -1 if none)")
      .def("begin_comb_stroke", [](std::shared_ptr<GuideGeometry> g, const DoubleArray& directions,
                                   const DoubleArray& weights, int n, double radius, const std::string& falloff,
                                   double strength) {
        check_n(n);
        CombStroke settings{{}, {}, radius, parse_falloff(falloff), strength};
        const TriangleMesh& mesh = g->mesh();
        return std::make_shared<CombStrokeInProgress>(
            CombStrokeInProgress{g, CombStrokeState(mesh, n, settings, to_comb(*g, directions, weights))});
      }, py::arg("directions"), py::arg("weights"), py::arg("n"), py::arg("radius"), py::arg("falloff") = "smooth",
         py::arg("strength") = 1.0,
         "A stroke on the comb field (directions (F,3), weights (F,)) that takes its samples in batches")
      .def("comb_guide", [](const GuideGeometry& g, const DoubleArray& directions, const DoubleArray& weights, int n) {
        check_n(n);
        return layer_tuple(comb_guide(g.mesh(), g.frames(), n, to_comb(g, directions, weights)));
      }, py::arg("directions"), py::arg("weights"), py::arg("n"));

  m.def("merge_hard_directions", [](const IndexArray& faces, const ComplexArray& directions, const IndexArray& sources,
                                    int n, double tolerance) {
    check_n(n);
    if (faces.ndim() != 1 || directions.ndim() != 1 || sources.ndim() != 1 || faces.shape(0) != directions.shape(0) ||
        faces.shape(0) != sources.shape(0))
      throw InputError("faces, directions and sources must be 1-D arrays of equal length");
    std::vector<HardDirection> proposals;
    for (py::ssize_t i = 0; i < faces.shape(0); ++i)
      proposals.push_back({static_cast<int>(faces.at(i)), directions.at(i), static_cast<int>(sources.at(i))});
    const MergedDirections merged = merge_hard_directions(std::move(proposals), n, tolerance);
    std::vector<int> f;
    std::vector<std::complex<double>> d;
    for (const auto& [face, dir] : merged.constraints) f.push_back(face), d.push_back(dir);
    py::list dropped;
    for (const auto& x : merged.dropped) dropped.append(py::make_tuple(x.face, x.source_a, x.source_b, x.degrees));
    return py::make_tuple(vector_array(f), vector_array(d), dropped);
  }, py::arg("faces"), py::arg("directions"), py::arg("sources"), py::arg("n"), py::arg("tolerance"),
        "(faces, unit directions, dropped [(face, source_a, source_b, degrees)])");

  py::class_<MirrorMap, std::shared_ptr<MirrorMap>>(m, "MirrorMap", py::module_local(),
                                                    "Faces matched to their mirror images (mirror.hpp)")
      .def(py::init([](std::shared_ptr<TriangleMesh> mesh, const std::string& axis, double offset, double tolerance) {
             const int a = parse_mirror_axis(axis);
             py::gil_scoped_release release;
             TangentFrames frames(*mesh);
             return std::make_shared<MirrorMap>(*mesh, frames, a, offset, tolerance);
           }),
           py::arg("mesh"), py::arg("axis"), py::arg("offset") = 0.0, py::arg("tolerance") = 0.0)
      .def_property_readonly("axis", &MirrorMap::axis)
      .def_property_readonly("offset", &MirrorMap::offset)
      .def_property_readonly("partner", [](const MirrorMap& mm) {
        std::vector<int> p(mm.num_faces());
        for (int f = 0; f < mm.num_faces(); ++f) p[f] = mm.partner(f);
        return vector_array(p);
      })
      .def_property_readonly("vertex_partner", [](const MirrorMap& mm) {
        std::vector<int> p(mm.num_vertices());
        for (int v = 0; v < mm.num_vertices(); ++v) p[v] = mm.vertex_partner(v);
        return vector_array(p);
      })
      .def_property_readonly("unmatched", [](const MirrorMap& mm) { return vector_array(mm.unmatched()); })
      .def_property_readonly("num_matched", &MirrorMap::num_matched)
      .def_property_readonly("max_mismatch", &MirrorMap::max_mismatch)
      .def("map", [](const MirrorMap& mm, const IndexArray& faces, const ComplexArray& z, int n) {
        check_n(n);
        if (faces.ndim() != 1 || z.ndim() != 1 || faces.shape(0) != z.shape(0))
          throw InputError("faces and values must be 1-D arrays of equal length");
        std::vector<std::complex<double>> out(static_cast<std::size_t>(faces.shape(0)));
        for (py::ssize_t i = 0; i < faces.shape(0); ++i) {
          const long long f = faces.at(i);
          if (f < 0 || f >= mm.num_faces() || mm.partner(static_cast<int>(f)) < 0)
            throw InputError("face " + std::to_string(f) + " has no mirror partner");
          out[i] = mm.map(static_cast<int>(f), z.at(i), n);
        }
        return vector_array(out);
      }, py::arg("faces"), py::arg("values"), py::arg("n"),
         "Representation vectors on the partner faces of the mirror images of `values`")
      .def("project", [](const MirrorMap& mm, const ComplexArray& z, int n) {
        check_n(n);
        if (z.ndim() != 1 || z.shape(0) != mm.num_faces()) throw InputError("field must have one value per face");
        const Eigen::VectorXcd p = mm.project(Eigen::Map<const Eigen::VectorXcd>(z.data(), z.shape(0)), n);
        py::array_t<std::complex<double>> out(p.size());
        std::copy(p.data(), p.data() + p.size(), out.mutable_data());
        return out;
      }, py::arg("field"), py::arg("n"), "(z + S z) / 2: the nearest symmetric field")
      .def("asymmetry", [](const MirrorMap& mm, const ComplexArray& z, int n) {
        check_n(n);
        if (z.ndim() != 1 || z.shape(0) != mm.num_faces()) throw InputError("field must have one value per face");
        return mm.asymmetry(Eigen::Map<const Eigen::VectorXcd>(z.data(), z.shape(0)), n);
      }, py::arg("field"), py::arg("n"), "max |z_partner - T z| / max |z| over matched faces");

  m.def("energy_rows", [](std::shared_ptr<FieldOperators> ops, int order, const IndexArray& faces) {
    if (faces.ndim() != 1) throw InputError("faces must be a 1-D integer array");
    std::vector<int> unknowns;
    for (py::ssize_t i = 0; i < faces.shape(0); ++i) {
      const long long f = faces.at(i);
      if (f < 0 || f >= ops->mesh().num_faces() || ops->unknown_of_face(static_cast<int>(f)) < 0)
        throw InputError("face " + std::to_string(f) + " is out of range or excluded");
      unknowns.push_back(ops->unknown_of_face(static_cast<int>(f)));
    }
    ComplexSparse E;
    {
      py::gil_scoped_release release;
      E = energy_rows(*ops, order, unknowns);
    }
    std::vector<long long> rows, cols;
    std::vector<std::complex<double>> vals;
    for (int k = 0; k < E.outerSize(); ++k)
      for (ComplexSparse::InnerIterator it(E, k); it; ++it) {
        rows.push_back(faces.at(it.row()));
        cols.push_back(ops->face_of_unknown(static_cast<int>(it.col())));
        vals.push_back(it.value());
      }
    return py::make_tuple(vector_array(rows), vector_array(cols), vector_array(vals));
  }, py::arg("ops"), py::arg("order"), py::arg("faces"),
        "COO triplets (face rows, face columns, values) of the rows `faces` of the energy matrix (energy_rows.hpp)");

  m.def("grow_faces", [](std::shared_ptr<TriangleMesh> mesh, const IndexArray& faces, int rings, long long limit) {
    if (faces.ndim() != 1) throw InputError("faces must be a 1-D integer array");
    if (rings < 0) throw ParameterError("rings must be >= 0");
    std::vector<int> seeds;
    for (py::ssize_t i = 0; i < faces.shape(0); ++i) {
      const long long f = faces.at(i);
      if (f < 0 || f >= mesh->num_faces()) throw InputError("face " + std::to_string(f) + " is out of range");
      seeds.push_back(static_cast<int>(f));
    }
    std::vector<std::pair<int, int>> reached;  // (face, dual steps from the seeds)
    {
      py::gil_scoped_release release;
      FaceWalker walker(*mesh);
      walker.rings(seeds, rings + 1, [&](int f, int ring) { reached.emplace_back(f, ring - 1); },
                   limit < 0 ? std::numeric_limits<std::size_t>::max() : static_cast<std::size_t>(limit));
      std::sort(reached.begin(), reached.end());
    }
    std::vector<int> out(reached.size()), steps(reached.size());
    for (std::size_t i = 0; i < reached.size(); ++i) out[i] = reached[i].first, steps[i] = reached[i].second;
    return py::make_tuple(vector_array(out), vector_array(steps));
  }, py::arg("mesh"), py::arg("faces"), py::arg("rings"), py::arg("limit") = -1,
        "(faces, steps): the active faces among `faces` and every active face within `rings` dual steps of them, "
        "sorted, and the number of dual steps from `faces` to each (0 for the given faces). With a limit >= 0 the "
        "walk ends with the first complete step that reaches more than `limit` faces");

  m.def("cut_mesh", [](std::shared_ptr<TriangleMesh> mesh, const py::object& edges) {
    const auto cuts = to_pairs(edges, "cut edges");
    CutMesh cut;
    {
      py::gil_scoped_release release;
      const MeshEdges table(*mesh);
      cut = cut_mesh(*mesh, table, cuts);
    }
    return py::make_tuple(std::const_pointer_cast<TriangleMesh>(cut.mesh), vector_array(cut.vertex_origin), cut.num_cut,
                          pairs_array(cut.unopened), pairs_array(cut.already_cut));
  }, py::arg("mesh"), py::arg("edges"),
        "The mesh cut open along edges: (mesh, vertex_origin, num_cut, unopened (k,2), already_cut (k,2))");
}

}  // namespace nfield::python
