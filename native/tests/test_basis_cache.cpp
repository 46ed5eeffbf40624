// The basis cache file (basis_cache.hpp): an exact round trip in both precisions, and the refusal of
// stale, truncated and corrupted files with a message naming the reason. A round trip through a binary
// file must reproduce every bit, so values and vectors are compared for exact equality.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <unistd.h>

#include "check.hpp"
#include "nfield/basis_cache.hpp"
#include "nfield/errors.hpp"
#include "nfield/spectral_basis.hpp"
#include "test_problems.hpp"

using namespace nfield;
using namespace nfield::test;
namespace fs = std::filesystem;

namespace {

/// A fresh directory under the system temp dir, removed with its content at the end of the test.
struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("nfield-basis-cache-" + std::to_string(::getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path, ignored);
  }
};

std::vector<char> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& p, const std::vector<char>& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

struct Fixture {
  std::shared_ptr<TriangleMesh> mesh = bumpy_torus(10, 12, 21);  // 240 faces
  std::shared_ptr<FieldOperators> ops = std::make_shared<FieldOperators>(mesh, 4);
  SpectralBasis basis = SpectralBasis::compute(*ops, 20);
  TempDir dir;
};

void round_trip_is_exact() {
  Fixture fx;
  for (const BasisPrecision precision : {BasisPrecision::Double, BasisPrecision::Single}) {
    const SpectralBasis original = fx.basis.with_precision(precision);
    const std::string path = (fx.dir.path / cache_key(*fx.ops, 20, precision)).string();
    save_basis(original, path);
    // Written through a temporary file and a rename: only the target is left.
    int files = 0;
    for (const auto& entry : fs::directory_iterator(fx.dir.path)) files += entry.is_regular_file();
    CHECK_EQ(files, precision == BasisPrecision::Double ? 1 : 2);
    const SpectralBasis loaded = load_basis(path, *fx.ops, 20, static_cast<int>(precision));
    CHECK(loaded.precision() == precision);
    CHECK(loaded.values() == original.values());
    CHECK(loaded.vectors_double() == original.vectors_double());
    CHECK(loaded.vectors_single() == original.vectors_single());
    CHECK(loaded.mass() == fx.ops->mass());
    CHECK(loaded.mesh_hash() == fx.mesh->content_hash());
    CHECK_EQ(loaded.n(), 4);
    // No expectations on k or precision: the file says.
    CHECK_EQ(load_basis(path, *fx.ops).size(), 20);
  }
  const std::string key = cache_key(*fx.ops, 20, BasisPrecision::Double);
  CHECK(key.rfind("basis-", 0) == 0);
  CHECK(key.find("-n4-geometric-N240-k20-f64") != std::string::npos);
  CHECK(cache_key(*fx.ops, 20, BasisPrecision::Single) != key);
  CHECK_THROWS(ParameterError, "empty", save_basis(SpectralBasis(), (fx.dir.path / "empty").string()));
}

void stale_files_are_refused() {
  Fixture fx;
  const std::string path = (fx.dir.path / "basis").string();
  save_basis(fx.basis, path);
  const FieldOperators other_n(fx.mesh, 2);
  const FieldOperators other_weights(fx.mesh, 4, EdgeWeights::Combinatorial);
  const FieldOperators other_mesh(bumpy_torus(10, 12, 22), 4);
  CHECK_THROWS(InputError, "symmetry n", load_basis(path, other_n));
  CHECK_THROWS(InputError, "edge weights", load_basis(path, other_weights));
  CHECK_THROWS(InputError, "mesh content", load_basis(path, other_mesh));
  CHECK_THROWS(InputError, "k (20 vs 19)", load_basis(path, *fx.ops, 19));
  CHECK_THROWS(InputError, "precision", load_basis(path, *fx.ops, 20, static_cast<int>(BasisPrecision::Single)));
  CHECK_THROWS(InputError, "cannot open", load_basis((fx.dir.path / "missing").string(), *fx.ops));
}

void corrupt_files_are_refused() {
  Fixture fx;
  const fs::path good = fx.dir.path / "good", bad = fx.dir.path / "bad";
  save_basis(fx.basis, good.string());
  const std::vector<char> bytes = read_bytes(good);
  // Layout (basis_cache.hpp): 40-byte header, k = 20 doubles, N x k complex<double>, 8-byte checksum.
  CHECK_EQ(static_cast<long long>(bytes.size()), 40 + 20 * 8 + 240 * 20 * 16 + 8);
  auto refused = [&](std::vector<char> changed, const char* reason) {
    write_bytes(bad, changed);
    CHECK_THROWS(InputError, reason, load_basis(bad.string(), *fx.ops));
  };
  std::vector<char> b = bytes;
  b[40 + 20 * 8 + 1234] ^= 0x10;  // one bit of one eigenvector entry
  refused(b, "checksum mismatch");
  b = bytes;
  b[40 + 3] ^= 0x01;  // one bit of one eigenvalue
  refused(b, "checksum mismatch");
  b = bytes;
  b[b.size() - 1] ^= 0x01;  // the checksum itself
  refused(b, "checksum mismatch");
  refused(std::vector<char>(bytes.begin(), bytes.end() - 5), "truncated or corrupt (size");
  b = bytes;
  b.push_back(0);
  refused(b, "truncated or corrupt (size");
  refused(std::vector<char>(bytes.begin(), bytes.begin() + 20), "truncated (no header)");
  b = bytes;
  b[0] = 'X';  // magic
  refused(b, "not an nfield spectral basis cache");
  b = bytes;
  b[8] = 2;  // version
  refused(b, "unsupported version");
  b = bytes;
  b[12] = 7;  // precision field
  refused(b, "corrupt (precision field)");
}

}  // namespace

int main() {
  run("round_trip_is_exact", round_trip_is_exact);
  run("stale_files_are_refused", stale_files_are_refused);
  run("corrupt_files_are_refused", corrupt_files_are_refused);
  return finish();
}
