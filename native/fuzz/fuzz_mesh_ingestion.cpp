// libFuzzer harness for mesh ingestion: raw arrays -> TriangleMesh -> FieldOperators (-> a tiny spline).
//
// The bytes are decoded into a small mesh so that the fuzzer spends its time on geometry and connectivity
// rather than on syntax (the parse_* targets cover files). Layout; missing bytes read as zero:
//   byte 0   bits 0-2: symmetry n (kSymmetries, including the invalid 0); bit 3: combinatorial weights;
//            bit 4: also solve a small spline; bits 5-7: coordinate scale (kScales, some outside the
//            supported extent [1e-12, 1e12])
//   byte 1   solver setup: bits 0-1 energy order - 1, bit 2 n-vector spline (else n-direction),
//            bit 3 a singularity at the first interior vertex, bits 4-7 constraint direction angle
//   byte 2   number of vertices V = 1 + byte % kMaxVertices
//   3 V coordinates, each a tag byte t: t < 224 a grid value (t - 112) / 8 * scale; 224..239 a special
//            value (kSpecials: NaN, inf, denormals, huge, tiny ...); t >= 240 the next 8 bytes as a double
//   the rest faces, 3 index bytes each (at most kMaxFaces): mostly b % V, some out of range or negative
//            (decode_index), and repeated indices arise naturally.
// Accepted outcomes: an nfield::Error at any stage; otherwise the results must keep the headers' promises
// (fuzz_checks.hpp) and the spline solution must be finite.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>

#include "fuzz_checks.hpp"
#include "nfield/errors.hpp"
#include "nfield/spline_solver.hpp"

namespace {

constexpr int kMaxVertices = 24;
constexpr int kMaxFaces = 48;
constexpr int kSymmetries[8] = {1, 2, 3, 4, 6, 8, 64, 0};
// Around the supported extent [1e-12, 1e12] (mesh.cpp): grid values span 1/8 .. 28, so 1e-11 and 1e11 land
// on both sides of the limits, 1e-13 and 1e13 mostly outside.
constexpr double kScales[8] = {1.0, 1.0, 1e-3, 1e3, 1e-11, 1e11, 1e-13, 1e13};
constexpr double kInf = std::numeric_limits<double>::infinity();
const double kSpecials[16] = {std::numeric_limits<double>::quiet_NaN(),
                              kInf,
                              -kInf,
                              0.0,
                              -0.0,
                              std::numeric_limits<double>::min(),
                              std::numeric_limits<double>::denorm_min(),
                              std::numeric_limits<double>::max(),
                              -std::numeric_limits<double>::max(),
                              1e-300,
                              1e300,
                              1e60,
                              -1e-60,
                              std::numeric_limits<double>::epsilon(),
                              1.0 + std::numeric_limits<double>::epsilon(),
                              -1e-7};

/// Sequential reader over the fuzzer's bytes; past the end it yields zeros.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t next() { return pos_ < size_ ? data_[pos_++] : 0; }
  double next_double() {
    unsigned char raw[8] = {0};
    for (unsigned char& b : raw) b = next();
    double value;
    std::memcpy(&value, raw, sizeof(value));
    return value;
  }
  std::size_t remaining() const { return size_ - pos_; }

 private:
  const std::uint8_t* data_;
  std::size_t size_, pos_ = 0;
};

double decode_coordinate(Bytes& in, double scale) {
  const std::uint8_t tag = in.next();
  if (tag < 224) return (tag - 112) / 8.0 * scale;
  if (tag < 240) return kSpecials[tag - 224];
  return in.next_double();
}

/// Mostly valid indices; 240..247 just past the end, 248/249/250 = -1, INT_MIN, INT_MAX.
int decode_index(std::uint8_t b, int num_vertices) {
  if (b >= 240 && b < 248) return num_vertices + (b - 240);
  if (b == 248) return -1;
  if (b == 249) return std::numeric_limits<int>::min();
  if (b == 250) return std::numeric_limits<int>::max();
  return b % num_vertices;
}

/// A small spline on the operators: one direction (or vector) constraint on the first active face,
/// optionally a singularity at the first interior vertex. Its solution must be finite.
void solve_spline(const std::shared_ptr<const nfield::FieldOperators>& ops, std::uint8_t setup) {
  const int order = 1 + (setup & 3);
  const auto kind = (setup & 4) ? nfield::SplineKind::Vector : nfield::SplineKind::Direction;
  const double angle = (setup >> 4) * (2.0 * 3.14159265358979323846 / 16.0);
  nfield::ExactSolver solver(ops, order, 1.0, nfield::ComplexVector(), kind);
  const nfield::TriangleMesh& mesh = ops->mesh();
  const int face = ops->face_of_unknown(0);
  if (kind == nfield::SplineKind::Vector)
    solver.set_vector_constraint(face, std::polar(1.0, angle));
  else
    solver.set_direction_constraint(face, std::polar(1.0, angle));
  if (setup & 8) {
    for (int v = 0; v < mesh.num_vertices(); ++v)
      if (mesh.vertex_is_interior(v)) {
        solver.set_singularity(v, 1);
        break;
      }
  }
  const nfield::ComplexVector w = solver.solve();
  FUZZ_CHECK(w.size() == mesh.num_faces());
  FUZZ_CHECK(w.allFinite());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Bytes in(data, size);
  const std::uint8_t flags = in.next();
  const std::uint8_t setup = in.next();
  const int n = kSymmetries[flags & 7];
  const auto weights = (flags & 8) ? nfield::EdgeWeights::Combinatorial : nfield::EdgeWeights::Geometric;
  const bool spline = (flags & 16) != 0;
  const double scale = kScales[flags >> 5];

  const int num_vertices = 1 + in.next() % kMaxVertices;
  nfield::Positions positions(num_vertices, 3);
  for (int v = 0; v < num_vertices; ++v)
    for (int k = 0; k < 3; ++k) positions(v, k) = decode_coordinate(in, scale);
  const int num_faces = static_cast<int>(std::min<std::size_t>(in.remaining() / 3, kMaxFaces));
  nfield::Triangles faces(num_faces, 3);
  for (int f = 0; f < num_faces; ++f)
    for (int k = 0; k < 3; ++k) faces(f, k) = decode_index(in.next(), num_vertices);

  try {
    auto mesh = std::make_shared<const nfield::TriangleMesh>(positions, faces);
    nfield_fuzz::check_mesh_invariants(*mesh);
    auto ops = std::make_shared<const nfield::FieldOperators>(mesh, n, weights);
    nfield_fuzz::check_operator_invariants(*ops);
    if (spline) solve_spline(ops, setup);
  } catch (const nfield::Error&) {
  }
  return 0;
}
