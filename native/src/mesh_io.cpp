// Mesh file readers: OBJ, OFF, PLY (ASCII and binary little-endian).
//
// All parsers work on an in-memory byte string and are written for hostile input (parse_mesh is a fuzzing
// entry point): every read is bounds-checked, counts announced by a header are checked against the bytes
// that are left before anything is reserved, and every container grows only with data actually read, so
// memory stays proportional to the input size. Numbers are parsed with std::from_chars (locale-independent).
// Every error is an InputError "<name>:<line>: <what>" (text) or "<name>: byte <offset>: <what>" (binary).
#include "nfield/mesh_io.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

constexpr std::int64_t kMaxInt = std::numeric_limits<int>::max();

// ------------------------------------------------------------------------------------------------ errors

[[noreturn]] void fail_at_line(const std::string& name, std::size_t line, const std::string& what) {
  throw InputError(name + ":" + std::to_string(line) + ": " + what);
}

[[noreturn]] void fail_at_byte(const std::string& name, std::size_t offset, const std::string& what) {
  throw InputError(name + ": byte " + std::to_string(offset) + ": " + what);
}

[[noreturn]] void fail(const std::string& name, const std::string& what) { throw InputError(name + ": " + what); }

/// A token quoted for an error message, shortened and with control bytes escaped.
std::string quote_token(std::string_view token) {
  constexpr std::size_t kMaxShown = 40;
  std::string out = "'";
  for (std::size_t i = 0; i < token.size() && i < kMaxShown; ++i) {
    const auto ch = static_cast<unsigned char>(token[i]);
    if (ch >= 0x20 && ch < 0x7f) {
      out += static_cast<char>(ch);
    } else {
      static const char* kHex = "0123456789abcdef";
      out += "\\x";
      out += kHex[ch >> 4];
      out += kHex[ch & 15];
    }
  }
  if (token.size() > kMaxShown) out += "...";
  return out + "'";
}

// ------------------------------------------------------------------------------------------------ text scanning

inline bool is_space(char ch) { return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\v' || ch == '\f'; }

/// Splits a text into lines ('\n'; a trailing '\r' is removed), counting line numbers from 1.
class LineReader {
 public:
  explicit LineReader(std::string_view text) : text_(text) {}
  /// Next line, or false at the end of the text.
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const std::size_t end = text_.find('\n', pos_);
    const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
    line = text_.substr(pos_, stop - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = end == std::string_view::npos ? text_.size() : end + 1;
    ++line_number_;
    return true;
  }
  std::size_t line_number() const { return line_number_; }
  /// Byte offset of the first byte after the last line returned.
  std::size_t offset() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t line_number_ = 0;
};

/// Splits one line into whitespace-separated tokens.
class Tokens {
 public:
  explicit Tokens(std::string_view line) : rest_(line) {}
  bool next(std::string_view& token) {
    std::size_t i = 0;
    while (i < rest_.size() && is_space(rest_[i])) ++i;
    if (i == rest_.size()) return false;
    std::size_t j = i;
    while (j < rest_.size() && !is_space(rest_[j])) ++j;
    token = rest_.substr(i, j - i);
    rest_.remove_prefix(j);
    return true;
  }
  /// Number of tokens left (does not consume them).
  std::size_t count() const {
    Tokens copy = *this;
    std::string_view token;
    std::size_t n = 0;
    while (copy.next(token)) ++n;
    return n;
  }

 private:
  std::string_view rest_;
};

/// The line without a '#' comment.
inline std::string_view strip_comment(std::string_view line) {
  const std::size_t hash = line.find('#');
  return hash == std::string_view::npos ? line : line.substr(0, hash);
}

inline bool is_blank(std::string_view line) {
  return std::all_of(line.begin(), line.end(), [](char ch) { return is_space(ch); });
}

/// Parses a whole token as a finite double (an optional leading '+' is accepted).
bool parse_double(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') {  // from_chars rejects a leading '+'
    token.remove_prefix(1);
    if (token.empty() || token.front() == '+' || token.front() == '-') return false;
  }
  const char* end = token.data() + token.size();
  const auto result = std::from_chars(token.data(), end, value);
  return result.ec == std::errc() && result.ptr == end && std::isfinite(value);
}

/// Parses a whole token as a signed 64-bit integer (an optional leading '+' is accepted).
bool parse_integer(std::string_view token, std::int64_t& value) {
  if (!token.empty() && token.front() == '+') {  // from_chars rejects a leading '+'
    token.remove_prefix(1);
    if (token.empty() || token.front() == '+' || token.front() == '-') return false;
  }
  const char* end = token.data() + token.size();
  const auto result = std::from_chars(token.data(), end, value);
  return result.ec == std::errc() && result.ptr == end;
}

/// Lowercase ASCII copy.
std::string to_lower(std::string_view text) {
  std::string out(text);
  for (char& ch : out)
    if (ch >= 'A' && ch <= 'Z') ch = static_cast<char>(ch - 'A' + 'a');
  return out;
}

// ------------------------------------------------------------------------------------------------ builder

/// Collects vertices and polygons; polygons are fan-triangulated: (v0, v_i, v_i+1), i = 1..k-2.
class MeshBuilder {
 public:
  explicit MeshBuilder(std::string name) : name_(std::move(name)) {}

  int num_vertices() const { return static_cast<int>(xyz_.size() / 3); }
  int num_polygons() const { return num_polygons_; }

  void reserve(std::size_t vertices, std::size_t triangles) {
    xyz_.reserve(3 * vertices);
    triangles_.reserve(3 * triangles);
    triangle_polygon_.reserve(triangles);
  }

  /// Adds a vertex (finite coordinates: the callers check).
  void add_vertex(double x, double y, double z) {
    if (num_vertices() >= kMaxInt) fail(name_, "too many vertices");
    xyz_.insert(xyz_.end(), {x, y, z});
  }

  /// Adds a polygon of k >= 3 vertex indices (the callers check k; indices are range-checked by finish()).
  void add_polygon(const std::vector<int>& polygon) {
    const std::int64_t new_triangles = static_cast<std::int64_t>(polygon.size()) - 2;
    if (num_polygons_ >= kMaxInt || static_cast<std::int64_t>(triangle_polygon_.size()) + new_triangles > kMaxInt / 3)
      fail(name_, "too many faces");
    for (std::size_t i = 1; i + 1 < polygon.size(); ++i) {
      triangles_.insert(triangles_.end(), {polygon[0], polygon[i], polygon[i + 1]});
      triangle_polygon_.push_back(num_polygons_);
    }
    ++num_polygons_;
  }

  /// Checks that there is something and every index is in range, and returns the arrays.
  MeshData finish() {
    if (xyz_.empty()) fail(name_, "no vertices");
    if (num_polygons_ == 0) fail(name_, "no faces");
    const int nv = num_vertices();
    for (std::size_t t = 0; t < triangle_polygon_.size(); ++t) {
      for (int k = 0; k < 3; ++k) {
        const int v = triangles_[3 * t + static_cast<std::size_t>(k)];
        if (v < 0 || v >= nv)
          fail(name_, "face " + std::to_string(triangle_polygon_[t]) + " references vertex " + std::to_string(v) +
                          " but there are only " + std::to_string(nv) + " vertices");
      }
    }
    MeshData data;
    const auto num_triangles = static_cast<Eigen::Index>(triangle_polygon_.size());
    data.positions = Eigen::Map<const Positions>(xyz_.data(), nv, 3);
    data.triangles = Eigen::Map<const Triangles>(triangles_.data(), num_triangles, 3);
    data.triangle_polygon = std::move(triangle_polygon_);
    data.num_polygons = num_polygons_;
    return data;
  }

 private:
  std::string name_;
  std::vector<double> xyz_;
  std::vector<int> triangles_;
  std::vector<int> triangle_polygon_;
  int num_polygons_ = 0;
};

// ------------------------------------------------------------------------------------------------ OBJ

/// Position index of one OBJ face token "v", "v/vt", "v//vn" or "v/vt/vn": 1-based, or negative relative to
/// the vertices defined so far (-1 = the last one). Returns the 0-based index (possibly >= the current count
/// for forward references, which are checked when the file is complete).
int obj_face_index(std::string_view token, int vertices_so_far, const std::string& name, std::size_t line) {
  const std::string_view number = token.substr(0, token.find('/'));
  std::int64_t value = 0;
  if (!parse_integer(number, value)) fail_at_line(name, line, "bad face vertex " + quote_token(token));
  if (value == 0) fail_at_line(name, line, "face vertex index 0 (OBJ indices start at 1)");
  if (value < 0) {
    const std::int64_t index = vertices_so_far + value;
    if (index < 0)
      fail_at_line(name, line, "relative index " + std::to_string(value) + " refers before the first vertex (only " +
                                   std::to_string(vertices_so_far) + " vertices so far)");
    return static_cast<int>(index);
  }
  if (value > kMaxInt) fail_at_line(name, line, "face vertex index " + std::to_string(value) + " is too large");
  return static_cast<int>(value - 1);
}

/// OBJ: 'v x y z [...]' and 'f a b c [...]' lines; everything else (vt, vn, g, o, s, usemtl, l, comments)
/// is ignored. Positive face indices may refer to vertices defined later; they are checked at the end.
MeshData parse_obj(std::string_view text, const std::string& name) {
  MeshBuilder builder(name);
  LineReader lines(text);
  std::string_view line, keyword, token;
  std::vector<int> polygon;
  int max_index = -1;
  std::size_t max_index_line = 0;
  while (lines.next(line)) {
    Tokens tokens(strip_comment(line));
    if (!tokens.next(keyword)) continue;
    const std::size_t line_number = lines.line_number();
    if (keyword == "v") {
      double xyz[3];
      for (double& coordinate : xyz) {
        if (!tokens.next(token)) fail_at_line(name, line_number, "vertex with fewer than 3 coordinates");
        if (!parse_double(token, coordinate)) fail_at_line(name, line_number, "bad coordinate " + quote_token(token));
      }
      builder.add_vertex(xyz[0], xyz[1], xyz[2]);
    } else if (keyword == "f") {
      polygon.clear();
      while (tokens.next(token)) {
        const int index = obj_face_index(token, builder.num_vertices(), name, line_number);
        if (index > max_index) {
          max_index = index;
          max_index_line = line_number;
        }
        polygon.push_back(index);
      }
      if (polygon.size() < 3)
        fail_at_line(name, line_number, "face with " + std::to_string(polygon.size()) + " vertices (at least 3 needed)");
      builder.add_polygon(polygon);
    }
  }
  if (max_index >= builder.num_vertices() && builder.num_vertices() > 0)
    fail_at_line(name, max_index_line, "face vertex index " + std::to_string(max_index + 1) + " but the file has only " +
                                           std::to_string(builder.num_vertices()) + " vertices");
  return builder.finish();
}

// ------------------------------------------------------------------------------------------------ OFF

/// Next line with content (comments removed, blank lines skipped).
bool next_content_line(LineReader& lines, std::string_view& content) {
  std::string_view line;
  while (lines.next(line)) {
    content = strip_comment(line);
    if (!is_blank(content)) return true;
  }
  return false;
}

/// True for the OFF header keywords [ST][C][N]OFF (texture coordinates, colours and normals are ignored).
bool is_off_keyword(std::string_view keyword) {
  if (keyword.size() >= 2 && keyword.substr(0, 2) == "ST") keyword.remove_prefix(2);
  if (!keyword.empty() && keyword.front() == 'C') keyword.remove_prefix(1);
  if (!keyword.empty() && keyword.front() == 'N') keyword.remove_prefix(1);
  return keyword == "OFF";
}

/// Reads a non-negative count that fits in int.
int parse_count(std::string_view token, const char* what, const std::string& name, std::size_t line) {
  std::int64_t value = 0;
  if (!parse_integer(token, value) || value < 0)
    fail_at_line(name, line, std::string("bad ") + what + " count " + quote_token(token));
  if (value > kMaxInt) fail_at_line(name, line, std::string(what) + " count " + std::to_string(value) + " is too large");
  return static_cast<int>(value);
}

/// OFF: header keyword, "nv nf [ne]" (possibly on the header line), nv vertex lines (x y z, extra columns
/// ignored), nf face lines "k i_1 .. i_k" (0-based; extra columns such as colours ignored).
MeshData parse_off(std::string_view text, const std::string& name) {
  MeshBuilder builder(name);
  LineReader lines(text);
  std::string_view content, token;
  if (!next_content_line(lines, content)) fail(name, "empty file");
  Tokens header(content);
  header.next(token);
  if (!is_off_keyword(token)) fail_at_line(name, lines.line_number(), "not an OFF file (header " + quote_token(token) + ")");
  // The counts usually follow on their own line, but may share the header line.
  Tokens counts = header;
  std::string_view first_count;
  if (Tokens(counts).next(first_count)) {
    if (first_count == "BINARY") fail_at_line(name, lines.line_number(), "binary OFF is not supported");
  } else {
    if (!next_content_line(lines, content)) fail(name, "missing vertex and face counts");
    counts = Tokens(content);
  }
  const std::size_t counts_line = lines.line_number();
  std::string_view nv_token, nf_token;
  if (!counts.next(nv_token) || !counts.next(nf_token))
    fail_at_line(name, counts_line, "expected vertex and face counts");
  const int nv = parse_count(nv_token, "vertex", name, counts_line);
  const int nf = parse_count(nf_token, "face", name, counts_line);
  // A vertex line needs at least 6 bytes ("0 0 0\n"), a face line at least 8 ("3 0 1 2\n").
  const std::size_t left = text.size() - lines.offset();
  if (static_cast<std::uint64_t>(nv) * 6 + static_cast<std::uint64_t>(nf) * 8 > static_cast<std::uint64_t>(left) + 2)
    fail_at_line(name, counts_line,
                 "file truncated: " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                     " faces cannot fit in the " + std::to_string(left) + " bytes that follow");
  builder.reserve(static_cast<std::size_t>(nv), static_cast<std::size_t>(nf));

  for (int i = 0; i < nv; ++i) {
    if (!next_content_line(lines, content))
      fail_at_line(name, lines.line_number(), "unexpected end of file: expected " + std::to_string(nv) +
                                                  " vertices, found " + std::to_string(i));
    Tokens tokens(content);
    double xyz[3];
    for (double& coordinate : xyz) {
      if (!tokens.next(token)) fail_at_line(name, lines.line_number(), "vertex with fewer than 3 coordinates");
      if (!parse_double(token, coordinate)) fail_at_line(name, lines.line_number(), "bad coordinate " + quote_token(token));
    }
    builder.add_vertex(xyz[0], xyz[1], xyz[2]);
  }

  std::vector<int> polygon;
  for (int j = 0; j < nf; ++j) {
    if (!next_content_line(lines, content))
      fail_at_line(name, lines.line_number(), "unexpected end of file: expected " + std::to_string(nf) +
                                                  " faces, found " + std::to_string(j));
    const std::size_t line = lines.line_number();
    Tokens tokens(content);
    tokens.next(token);
    std::int64_t k = 0;
    if (!parse_integer(token, k) || k < 0) fail_at_line(name, line, "bad face vertex count " + quote_token(token));
    if (k < 3) fail_at_line(name, line, "face with " + std::to_string(k) + " vertices (at least 3 needed)");
    if (static_cast<std::uint64_t>(k) > tokens.count())
      fail_at_line(name, line, "face announces " + std::to_string(k) + " vertices but the line lists only " +
                                   std::to_string(tokens.count()));
    polygon.clear();
    for (std::int64_t i = 0; i < k; ++i) {
      tokens.next(token);
      std::int64_t index = 0;
      if (!parse_integer(token, index)) fail_at_line(name, line, "bad vertex index " + quote_token(token));
      if (index < 0 || index >= nv)
        fail_at_line(name, line, "vertex index " + std::to_string(index) + " out of range 0.." + std::to_string(nv - 1));
      polygon.push_back(static_cast<int>(index));
    }
    builder.add_polygon(polygon);
  }
  return builder.finish();
}

// ------------------------------------------------------------------------------------------------ PLY

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

bool parse_ply_type(std::string_view word, PlyType& type) {
  static const std::pair<const char*, PlyType> kNames[] = {
      {"char", PlyType::Int8},     {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
      {"uint8", PlyType::UInt8},   {"short", PlyType::Int16},     {"int16", PlyType::Int16},
      {"ushort", PlyType::UInt16}, {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
      {"int32", PlyType::Int32},   {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
      {"float", PlyType::Float32}, {"float32", PlyType::Float32}, {"double", PlyType::Float64},
      {"float64", PlyType::Float64}};
  for (const auto& entry : kNames)
    if (word == entry.first) {
      type = entry.second;
      return true;
    }
  return false;
}

std::size_t ply_type_size(PlyType type) {
  switch (type) {
    case PlyType::Int8:
    case PlyType::UInt8: return 1;
    case PlyType::Int16:
    case PlyType::UInt16: return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32: return 4;
    case PlyType::Float64: return 8;
  }
  return 8;
}

bool ply_type_is_integer(PlyType type) { return type != PlyType::Float32 && type != PlyType::Float64; }

/// Range of an integer type, as doubles (exact).
std::pair<double, double> ply_integer_range(PlyType type) {
  switch (type) {
    case PlyType::Int8: return {-128.0, 127.0};
    case PlyType::UInt8: return {0.0, 255.0};
    case PlyType::Int16: return {-32768.0, 32767.0};
    case PlyType::UInt16: return {0.0, 65535.0};
    case PlyType::Int32: return {-2147483648.0, 2147483647.0};
    case PlyType::UInt32: return {0.0, 4294967295.0};
    case PlyType::Float32:
    case PlyType::Float64: break;
  }
  return {-std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
}

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::UInt8;  ///< lists only
  PlyType type = PlyType::Float32;      ///< scalar type, or list entry type
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;

  /// Smallest number of bytes one element occupies in a binary file (lists of length zero).
  std::uint64_t min_binary_size() const {
    std::uint64_t size = 0;
    for (const PlyProperty& p : properties) size += ply_type_size(p.is_list ? p.count_type : p.type);
    return size;
  }
};

enum class PlyFormat { Ascii, BinaryLittleEndian };

struct PlyHeader {
  PlyFormat format = PlyFormat::Ascii;
  std::vector<PlyElement> elements;
  std::size_t body_offset = 0;  ///< first byte after the end_header line
  std::size_t body_line = 0;    ///< line number of the first body line (ASCII)
};

/// Parses the header up to and including "end_header".
PlyHeader parse_ply_header(std::string_view text, const std::string& name) {
  PlyHeader header;
  LineReader lines(text);
  std::string_view line, word;
  if (!lines.next(line) || line != "ply") fail(name, "not a PLY file (the first line must be 'ply')");
  bool have_format = false, have_end = false;
  while (!have_end && lines.next(line)) {
    const std::size_t n = lines.line_number();
    Tokens tokens(line);
    if (!tokens.next(word)) continue;
    if (word == "comment" || word == "obj_info") continue;
    if (word == "format") {
      std::string_view kind;
      tokens.next(kind);
      if (kind == "ascii") {
        header.format = PlyFormat::Ascii;
      } else if (kind == "binary_little_endian") {
        header.format = PlyFormat::BinaryLittleEndian;
      } else if (kind == "binary_big_endian") {
        fail_at_line(name, n, "PLY format binary_big_endian is not supported (convert to little endian or ASCII)");
      } else {
        fail_at_line(name, n, "unknown PLY format " + quote_token(kind));
      }
      have_format = true;
    } else if (word == "element") {
      std::string_view element_name, count_token;
      if (!tokens.next(element_name) || !tokens.next(count_token))
        fail_at_line(name, n, "element line needs a name and a count");
      std::int64_t count = 0;
      if (!parse_integer(count_token, count) || count < 0)
        fail_at_line(name, n, "bad element count " + quote_token(count_token));
      header.elements.push_back({std::string(element_name), static_cast<std::uint64_t>(count), {}});
    } else if (word == "property") {
      if (header.elements.empty()) fail_at_line(name, n, "property before any element");
      PlyProperty property;
      std::string_view type_word, property_name;
      if (!tokens.next(type_word)) fail_at_line(name, n, "property line needs a type");
      if (type_word == "list") {
        std::string_view count_word;
        property.is_list = true;
        if (!tokens.next(count_word) || !parse_ply_type(count_word, property.count_type) ||
            !ply_type_is_integer(property.count_type))
          fail_at_line(name, n, "list property needs an integer count type");
        if (!tokens.next(type_word)) fail_at_line(name, n, "list property needs an entry type");
      }
      if (!parse_ply_type(type_word, property.type)) fail_at_line(name, n, "unknown property type " + quote_token(type_word));
      if (!tokens.next(property_name)) fail_at_line(name, n, "property line needs a name");
      property.name = std::string(property_name);
      header.elements.back().properties.push_back(property);
    } else if (word == "end_header") {
      have_end = true;
    } else {
      fail_at_line(name, n, "unexpected header line " + quote_token(line));
    }
  }
  if (!have_end) fail(name, "PLY header without end_header");
  if (!have_format) fail(name, "PLY header without a format line");
  header.body_offset = lines.offset();
  header.body_line = lines.line_number() + 1;
  return header;
}

/// A number for an error message ("-1", "4294967295", "1e+300").
std::string format_number(double value) {
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

/// " (element 'face' #12)" for error messages, or "" outside any element.
std::string context(const std::string* element, std::uint64_t index) {
  return element ? " (element '" + *element + "' #" + std::to_string(index) + ")" : "";
}

/// Reads binary little-endian values with bounds checks.
class PlyBinaryReader {
 public:
  PlyBinaryReader(std::string_view data, std::size_t offset, const std::string& name)
      : data_(data), pos_(offset), name_(name) {}

  std::size_t remaining() const { return data_.size() - pos_; }
  /// Smallest number of bytes one entry of the element occupies (lists of length zero).
  static std::uint64_t min_entry_size(const PlyElement& element) { return element.min_binary_size(); }

  /// Value of one scalar of the given type, as double (exact for every integer type).
  double read(PlyType type) {
    const std::size_t size = ply_type_size(type);
    require(size);
    std::uint64_t bits = 0;
    for (std::size_t i = 0; i < size; ++i)
      bits |= static_cast<std::uint64_t>(static_cast<unsigned char>(data_[pos_ + i])) << (8 * i);
    pos_ += size;
    switch (type) {
      case PlyType::Int8: return static_cast<double>(static_cast<std::int8_t>(static_cast<std::uint8_t>(bits)));
      case PlyType::UInt8: return static_cast<double>(static_cast<std::uint8_t>(bits));
      case PlyType::Int16: return static_cast<double>(static_cast<std::int16_t>(static_cast<std::uint16_t>(bits)));
      case PlyType::UInt16: return static_cast<double>(static_cast<std::uint16_t>(bits));
      case PlyType::Int32: return static_cast<double>(static_cast<std::int32_t>(static_cast<std::uint32_t>(bits)));
      case PlyType::UInt32: return static_cast<double>(static_cast<std::uint32_t>(bits));
      case PlyType::Float32: {
        const auto word = static_cast<std::uint32_t>(bits);
        float value;
        std::memcpy(&value, &word, sizeof(value));
        return static_cast<double>(value);
      }
      case PlyType::Float64: {
        double value;
        std::memcpy(&value, &bits, sizeof(value));
        return value;
      }
    }
    return 0;
  }

  /// Skips `count` values of the given type.
  void skip(PlyType type, std::uint64_t count) {
    const std::uint64_t size = ply_type_size(type);
    if (count > remaining() / size) error("unexpected end of data");
    pos_ += static_cast<std::size_t>(count * size);
  }

  /// Checks that a list of `count` entries of the given type is present.
  void require_list(PlyType type, std::uint64_t count) {
    if (count > remaining() / ply_type_size(type))
      error("list of " + std::to_string(count) + " entries runs past the end of the data");
  }

  /// Names the element entry being read in error messages.
  void set_context(const std::string* element, std::uint64_t index) {
    element_ = element;
    index_ = index;
  }
  [[noreturn]] void error(const std::string& what) const { fail_at_byte(name_, pos_, what + context(element_, index_)); }

 private:
  void require(std::size_t size) const {
    if (size > remaining()) error("unexpected end of data");
  }
  std::string_view data_;
  std::size_t pos_;
  const std::string& name_;
  const std::string* element_ = nullptr;
  std::uint64_t index_ = 0;
};

/// Reads whitespace-separated ASCII values, tracking line numbers.
class PlyAsciiReader {
 public:
  PlyAsciiReader(std::string_view data, std::size_t offset, std::size_t line, const std::string& name)
      : data_(data), pos_(offset), line_(line), name_(name) {}

  std::size_t remaining() const { return data_.size() - pos_; }
  /// Every value takes at least one character.
  static std::uint64_t min_entry_size(const PlyElement& element) { return element.properties.size(); }

  double read(PlyType type) {
    const std::string_view token = next_token();
    double value = 0;
    if (!parse_double(token, value)) error("bad number " + quote_token(token));
    if (ply_type_is_integer(type)) {
      if (value != std::floor(value)) error("non-integer value " + quote_token(token) + " for an integer property");
      const auto [lowest, highest] = ply_integer_range(type);
      if (value < lowest || value > highest) error("value " + quote_token(token) + " out of range for its integer type");
    }
    return value;
  }

  void skip(PlyType, std::uint64_t count) {
    for (std::uint64_t i = 0; i < count; ++i) next_token();
  }

  /// Entries are read one by one; running out of tokens is reported then.
  void require_list(PlyType, std::uint64_t) {}

  /// Names the element entry being read in error messages.
  void set_context(const std::string* element, std::uint64_t index) {
    element_ = element;
    index_ = index;
  }
  [[noreturn]] void error(const std::string& what) const { fail_at_line(name_, line_, what + context(element_, index_)); }

 private:
  std::string_view next_token() {
    while (pos_ < data_.size() && (is_space(data_[pos_]) || data_[pos_] == '\n')) {
      if (data_[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ == data_.size()) error("unexpected end of file");
    const std::size_t start = pos_;
    while (pos_ < data_.size() && !is_space(data_[pos_]) && data_[pos_] != '\n') ++pos_;
    return data_.substr(start, pos_ - start);
  }

  std::string_view data_;
  std::size_t pos_;
  std::size_t line_;
  const std::string& name_;
  const std::string* element_ = nullptr;
  std::uint64_t index_ = 0;
};

/// Index of the property with one of the given names in the element, or -1.
int find_property(const PlyElement& element, std::initializer_list<const char*> names) {
  for (std::size_t i = 0; i < element.properties.size(); ++i)
    for (const char* candidate : names)
      if (element.properties[i].name == candidate) return static_cast<int>(i);
  return -1;
}

/// Reads a list length (a non-negative integer).
template <class Reader>
std::uint64_t read_list_length(Reader& reader, PlyType type) {
  const double value = reader.read(type);  // an integer within the range of its type (at most 2^32 - 1)
  if (value < 0) reader.error("negative list length");
  return static_cast<std::uint64_t>(value);
}

/// Reads the data of every element in header order: vertex x/y/z and face vertex_indices are kept, all other
/// properties and elements are skipped.
template <class Reader>
MeshData read_ply_body(Reader& reader, const PlyHeader& header, const std::string& name) {
  MeshBuilder builder(name);
  bool have_vertices = false, have_faces = false;
  std::vector<int> polygon;
  for (const PlyElement& element : header.elements) {
    reader.set_context(nullptr, 0);
    if (element.count == 0 || element.properties.empty()) continue;
    // Check the announced count against the bytes left before reserving anything.
    const std::uint64_t min_size = std::max<std::uint64_t>(1, Reader::min_entry_size(element));
    if (element.count > reader.remaining() / min_size)
      reader.error("element '" + element.name + "' announces " + std::to_string(element.count) +
                   " entries, more than the " + std::to_string(reader.remaining()) + " bytes left can hold");

    int wanted[3] = {-1, -1, -1};  // x, y, z or the face index list
    const bool is_vertex = element.name == "vertex";
    const bool is_face = element.name == "face";
    if (is_vertex) {
      if (have_vertices) reader.error("more than one vertex element");
      have_vertices = true;
      const char* axes[3] = {"x", "y", "z"};
      for (int k = 0; k < 3; ++k) {
        wanted[k] = find_property(element, {axes[k]});
        if (wanted[k] < 0) fail(name, std::string("vertex element has no property '") + axes[k] + "'");
        if (element.properties[static_cast<std::size_t>(wanted[k])].is_list)
          fail(name, std::string("vertex property '") + axes[k] + "' is a list");
      }
      if (element.count > static_cast<std::uint64_t>(kMaxInt)) fail(name, "too many vertices");
      builder.reserve(static_cast<std::size_t>(element.count), 0);
    } else if (is_face) {
      if (have_faces) reader.error("more than one face element");
      have_faces = true;
      wanted[0] = find_property(element, {"vertex_indices", "vertex_index"});
      if (wanted[0] < 0) fail(name, "face element has no property 'vertex_indices' or 'vertex_index'");
      const PlyProperty& list = element.properties[static_cast<std::size_t>(wanted[0])];
      if (!list.is_list || !ply_type_is_integer(list.type))
        fail(name, "face property '" + list.name + "' must be a list of integers");
      if (element.count > static_cast<std::uint64_t>(kMaxInt)) fail(name, "too many faces");
    }

    for (std::uint64_t item = 0; item < element.count; ++item) {
      reader.set_context(&element.name, item);
      double xyz[3] = {0, 0, 0};
      polygon.clear();
      for (std::size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        const int pi = static_cast<int>(p);
        if (!property.is_list) {
          if (is_vertex && (pi == wanted[0] || pi == wanted[1] || pi == wanted[2])) {
            const double value = reader.read(property.type);
            xyz[pi == wanted[0] ? 0 : (pi == wanted[1] ? 1 : 2)] = value;
            // A property listed twice (x x y z) just overwrites; fine.
          } else {
            reader.skip(property.type, 1);
          }
          continue;
        }
        const std::uint64_t length = read_list_length(reader, property.count_type);
        reader.require_list(property.type, length);
        if (is_face && pi == wanted[0]) {
          if (length < 3) reader.error("face with " + std::to_string(length) + " vertices (at least 3 needed)");
          for (std::uint64_t i = 0; i < length; ++i) {
            const double index = reader.read(property.type);
            if (index < 0 || index > static_cast<double>(kMaxInt))
              reader.error("invalid vertex index " + format_number(index));
            polygon.push_back(static_cast<int>(index));
          }
        } else {
          reader.skip(property.type, length);
        }
      }
      if (is_vertex) {
        if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2]))
          reader.error("non-finite vertex coordinate");
        builder.add_vertex(xyz[0], xyz[1], xyz[2]);
      } else if (is_face) {
        builder.add_polygon(polygon);  // length >= 3 checked above
      }
    }
  }
  return builder.finish();
}

MeshData parse_ply(std::string_view text, const std::string& name) {
  const PlyHeader header = parse_ply_header(text, name);
  if (header.format == PlyFormat::Ascii) {
    PlyAsciiReader reader(text, header.body_offset, header.body_line, name);
    return read_ply_body(reader, header, name);
  }
  PlyBinaryReader reader(text, header.body_offset, name);
  return read_ply_body(reader, header, name);
}

// ------------------------------------------------------------------------------------------------ files

/// The whole file as bytes. Only regular files are read (a directory or device is an error).
std::string read_file(const std::string& path) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (error || !std::filesystem::exists(status)) throw InputError(path + ": no such file");
  if (!std::filesystem::is_regular_file(status)) throw InputError(path + ": not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open file");
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad() || bytes.bad()) throw InputError(path + ": read error");
  return std::move(bytes).str();
}

/// Lowercase extension without the dot ("" if none).
std::string extension_of(const std::string& path) {
  const std::size_t slash = path.find_last_of("/\\");
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return to_lower(std::string_view(path).substr(dot + 1));
}

MeshData parse_named(const std::string& bytes, const std::string& format, const std::string& name) {
  if (format == "obj") return parse_obj(bytes, name);
  if (format == "off") return parse_off(bytes, name);
  if (format == "ply") return parse_ply(bytes, name);
  throw InputError(name + ": unsupported mesh format " + quote_token(format) + " (expected obj, off or ply)");
}

}  // namespace

MeshData read_mesh(const std::string& path) {
  const std::string format = extension_of(path);
  if (format != "obj" && format != "off" && format != "ply")
    throw InputError(path + ": unsupported file extension (expected .obj, .off or .ply)");
  return parse_named(read_file(path), format, path);
}

MeshData read_obj(const std::string& path) { return parse_named(read_file(path), "obj", path); }
MeshData read_off(const std::string& path) { return parse_named(read_file(path), "off", path); }
MeshData read_ply(const std::string& path) { return parse_named(read_file(path), "ply", path); }

MeshData parse_mesh(const std::string& bytes, const std::string& format) {
  const std::string lower = to_lower(format);
  return parse_named(bytes, lower, "<" + lower + " data>");
}

}  // namespace nfield
