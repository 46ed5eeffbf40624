#include "nfield/basis_cache.hpp"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <new>
#include <random>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

constexpr char kMagic[8] = {'N', 'F', 'B', 'A', 'S', 'I', 'S', '1'};
constexpr std::uint32_t kVersion = 1;

struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t precision;  // 0 double, 1 single
  std::uint64_t mesh_hash;
  std::int32_t n;
  std::int32_t weights;  // 0 geometric, 1 combinatorial
  std::int32_t k;
  std::int32_t num_unknowns;
};
static_assert(sizeof(Header) == 40, "unexpected header padding");

/// Seed of the checksum chain.
constexpr std::uint64_t kChecksumSeed = 0x6e6669656c64ULL;

/// A fast 64-bit checksum (word-wise multiply-xorshift) of a byte range, chained through `h`.
std::uint64_t checksum(const void* data, std::size_t bytes, std::uint64_t h) {
  const unsigned char* p = static_cast<const unsigned char*>(data);
  std::size_t i = 0;
  for (; i + 8 <= bytes; i += 8) {
    std::uint64_t w;
    std::memcpy(&w, p + i, 8);
    h ^= w + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    h *= 0xff51afd7ed558ccdULL;
  }
  for (; i < bytes; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h ^ (h >> 33);
}

std::string hex64(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

}  // namespace

std::string cache_key(const FieldOperators& ops, int k, BasisPrecision precision) {
  return "basis-" + hex64(ops.mesh().content_hash()) + "-n" + std::to_string(ops.n()) + "-" +
         to_string(ops.weights()) + "-N" + std::to_string(ops.num_unknowns()) + "-k" + std::to_string(k) +
         (precision == BasisPrecision::Single ? "-f32" : "-f64");
}

void save_basis(const SpectralBasis& basis, const std::string& path) {
  if (basis.size() == 0) throw ParameterError("cannot save an empty spectral basis");
  Header h{};
  std::memcpy(h.magic, kMagic, 8);
  h.version = kVersion;
  h.precision = basis.precision() == BasisPrecision::Single ? 1 : 0;
  h.mesh_hash = basis.mesh_hash();
  h.n = basis.n();
  h.weights = basis.weights() == EdgeWeights::Geometric ? 0 : 1;
  h.k = basis.size();
  h.num_unknowns = basis.num_unknowns();
  const bool single = basis.precision() == BasisPrecision::Single;
  const void* vec = single ? static_cast<const void*>(basis.vectors_single().data())
                           : static_cast<const void*>(basis.vectors_double().data());
  const std::size_t vec_bytes = single ? static_cast<std::size_t>(basis.vectors_single().size()) * sizeof(std::complex<float>)
                                       : static_cast<std::size_t>(basis.vectors_double().size()) * sizeof(Complex);
  const std::size_t val_bytes = static_cast<std::size_t>(basis.values().size()) * sizeof(double);
  std::uint64_t sum = checksum(&h, sizeof h, kChecksumSeed);
  sum = checksum(basis.values().data(), val_bytes, sum);
  sum = checksum(vec, vec_bytes, sum);

  std::random_device rd;
  const std::string tmp = path + ".tmp" + hex64((static_cast<std::uint64_t>(rd()) << 32) ^ rd());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError("cannot write spectral basis cache '" + tmp + "'");
    out.write(reinterpret_cast<const char*>(&h), sizeof h);
    out.write(reinterpret_cast<const char*>(basis.values().data()), static_cast<std::streamsize>(val_bytes));
    out.write(static_cast<const char*>(vec), static_cast<std::streamsize>(vec_bytes));
    out.write(reinterpret_cast<const char*>(&sum), sizeof sum);
    out.flush();
    if (!out) {
      out.close();
      std::remove(tmp.c_str());
      throw InputError("writing spectral basis cache '" + tmp + "' failed (disk full?)");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw InputError("cannot move spectral basis cache into place at '" + path + "'");
  }
}

SpectralBasis load_basis(const std::string& path, const FieldOperators& ops, int expected_k, int expected_precision) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError("cannot open spectral basis cache '" + path + "'");
  const std::streamoff file_size = in.tellg();
  in.seekg(0);
  Header h{};
  if (file_size < static_cast<std::streamoff>(sizeof h) || !in.read(reinterpret_cast<char*>(&h), sizeof h))
    throw InputError("spectral basis cache '" + path + "' is truncated (no header)");
  if (std::memcmp(h.magic, kMagic, 8) != 0) throw InputError("'" + path + "' is not an nfield spectral basis cache");
  if (h.version != kVersion)
    throw InputError("spectral basis cache '" + path + "' has unsupported version " + std::to_string(h.version));
  auto stale = [&](const std::string& what) {
    return InputError("stale spectral basis cache '" + path + "': " + what + " does not match");
  };
  if (h.mesh_hash != ops.mesh().content_hash()) throw stale("mesh content");
  if (h.n != ops.n()) throw stale("symmetry n (" + std::to_string(h.n) + " vs " + std::to_string(ops.n()) + ")");
  if (h.weights != (ops.weights() == EdgeWeights::Geometric ? 0 : 1)) throw stale("edge weights");
  if (h.num_unknowns != ops.num_unknowns()) throw stale("number of unknowns");
  if (h.precision > 1) throw InputError("spectral basis cache '" + path + "' is corrupt (precision field)");
  if (expected_k > 0 && h.k != expected_k) throw stale("k (" + std::to_string(h.k) + " vs " + std::to_string(expected_k) + ")");
  if (expected_precision >= 0 && static_cast<int>(h.precision) != expected_precision) throw stale("precision");
  if (h.k < 1 || h.k > h.num_unknowns) throw InputError("spectral basis cache '" + path + "' is corrupt (k)");

  const std::size_t N = static_cast<std::size_t>(h.num_unknowns), k = static_cast<std::size_t>(h.k);
  const std::size_t scalar = h.precision == 1 ? sizeof(std::complex<float>) : sizeof(Complex);
  const std::size_t val_bytes = k * sizeof(double), vec_bytes = N * k * scalar;
  const std::size_t expected = sizeof h + val_bytes + vec_bytes + sizeof(std::uint64_t);
  if (static_cast<std::size_t>(file_size) != expected)
    throw InputError("spectral basis cache '" + path + "' is truncated or corrupt (size " + std::to_string(file_size) +
                     " bytes, expected " + std::to_string(expected) + ")");

  SpectralBasis out;
  try {
    out.values_.resize(static_cast<Eigen::Index>(k));
    if (h.precision == 1)
      out.vectors_f_.resize(static_cast<Eigen::Index>(N), static_cast<Eigen::Index>(k));
    else
      out.vectors_d_.resize(static_cast<Eigen::Index>(N), static_cast<Eigen::Index>(k));
  } catch (const std::bad_alloc&) {
    throw SolverError("not enough memory to load spectral basis cache '" + path + "'");
  }
  void* vec = h.precision == 1 ? static_cast<void*>(out.vectors_f_.data()) : static_cast<void*>(out.vectors_d_.data());
  std::uint64_t stored = 0;
  if (!in.read(reinterpret_cast<char*>(out.values_.data()), static_cast<std::streamsize>(val_bytes)) ||
      !in.read(static_cast<char*>(vec), static_cast<std::streamsize>(vec_bytes)) ||
      !in.read(reinterpret_cast<char*>(&stored), sizeof stored))
    throw InputError("spectral basis cache '" + path + "' is truncated");
  std::uint64_t sum = checksum(&h, sizeof h, kChecksumSeed);
  sum = checksum(out.values_.data(), val_bytes, sum);
  sum = checksum(vec, vec_bytes, sum);
  if (sum != stored) throw InputError("spectral basis cache '" + path + "' is corrupt (checksum mismatch)");
  if (!out.values_.allFinite()) throw InputError("spectral basis cache '" + path + "' is corrupt (eigenvalues)");
  out.mass_ = ops.mass();
  out.precision_ = h.precision == 1 ? BasisPrecision::Single : BasisPrecision::Double;
  out.mesh_hash_ = h.mesh_hash;
  out.n_ = h.n;
  out.weights_ = ops.weights();
  return out;
}

}  // namespace nfield
