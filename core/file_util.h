// Small file helpers shared by every reader and writer: text lines with their line numbers, and
// atomic writes (temporary name + rename, DESIGN.md §2) so that a killed or failed run never
// leaves a half-written output behind.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace genscene {

struct TextLine {
  int number = 0;    // 1-based line number in the file, for error messages
  std::string text;  // without the line ending; surrounding whitespace trimmed
};

// Reads a text file. Throws Error("<path>: cannot open") when it cannot be read.
std::string ReadTextFile(const std::filesystem::path& path);

// The non-empty lines of a text file that are not comments (starting with '#').
std::vector<TextLine> ReadDataLines(const std::filesystem::path& path);

// Splits on whitespace.
std::vector<std::string> SplitWhitespace(const std::string& text);

// Parses a number; throws Error("<where>: '<token>' is not a number") on failure.
double ParseDouble(const std::string& token, const std::string& where);
long long ParseInteger(const std::string& token, const std::string& where);
// ParseInteger, and an Error naming the token when it does not fit in an int.
int ParseInt32(const std::string& token, const std::string& where);

// Calls write(tmp) with a temporary path in the same folder as `path`, then renames tmp to `path`.
// If write throws, the temporary file is removed and the exception propagates: `path` is either
// the complete new file or untouched. Creates the parent folder when missing.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(const std::filesystem::path& tmp)>& write);

// Writes text atomically.
void WriteTextFileAtomically(const std::filesystem::path& path, const std::string& text);

// The temporary name WriteFileAtomically uses for `path`, keeping its extension so that writers
// which choose the format by extension (OpenCV, OpenMesh) still work: "a/mesh.ply" ->
// "a/mesh.tmp-<pid>.ply".
std::filesystem::path TemporaryPathFor(const std::filesystem::path& path);

// Resolves a path found inside a list file: relative paths are relative to the list's folder.
std::filesystem::path ResolveRelativeTo(const std::filesystem::path& list_file,
                                        const std::string& entry);

// 64-bit FNV-1a of `size` bytes, continuing from `hash` (start: kFnv1aOffset).
constexpr uint64_t kFnv1aOffset = 14695981039346656037ull;
uint64_t Fnv1a64(const void* data, size_t size, uint64_t hash = kFnv1aOffset);
inline uint64_t Fnv1a64(const std::string& text, uint64_t hash = kFnv1aOffset) {
  return Fnv1a64(text.data(), text.size(), hash);
}

// FNV-1a 64 of a file's bytes, or of every regular file below a folder (in sorted order of their
// relative paths, each path and its bytes): the same content gives the same fingerprint wherever
// it lies and whatever its time stamps. Throws Error naming the file that cannot be read.
uint64_t ContentFingerprint(const std::filesystem::path& path);

}  // namespace genscene
