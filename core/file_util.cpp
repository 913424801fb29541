#include "core/file_util.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <system_error>

#include "core/check.h"

namespace genscene {

namespace fs = std::filesystem;

namespace {

std::string Trim(const std::string& s) {
  const auto begin = s.find_first_not_of(" \t\r\n");
  if (begin == std::string::npos) return "";
  const auto end = s.find_last_not_of(" \t\r\n");
  return s.substr(begin, end - begin + 1);
}

}  // namespace

std::string ReadTextFile(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(Format(path.string(), ": file not found"));
  if (fs::is_directory(path, ec)) throw Error(Format(path.string(), ": is a folder, not a file"));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(Format(path.string(), ": cannot open (", std::strerror(errno), ")"));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<TextLine> ReadDataLines(const fs::path& path) {
  const std::string text = ReadTextFile(path);
  std::vector<TextLine> lines;
  std::istringstream in(text);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    lines.push_back({number, std::move(trimmed)});
  }
  return lines;
}

std::vector<std::string> SplitWhitespace(const std::string& text) {
  std::vector<std::string> tokens;
  std::istringstream in(text);
  std::string token;
  while (in >> token) tokens.push_back(token);
  return tokens;
}

double ParseDouble(const std::string& token, const std::string& where) {
  try {
    size_t used = 0;
    const double value = std::stod(token, &used);
    if (used == token.size()) return value;
  } catch (const std::exception&) {
  }
  throw Error(Format(where, ": '", token, "' is not a number"));
}

long long ParseInteger(const std::string& token, const std::string& where) {
  try {
    size_t used = 0;
    const long long value = std::stoll(token, &used);
    if (used == token.size()) return value;
  } catch (const std::exception&) {
  }
  throw Error(Format(where, ": '", token, "' is not an integer"));
}

int ParseInt32(const std::string& token, const std::string& where) {
  const long long value = ParseInteger(token, where);
  if (value < std::numeric_limits<int>::min() || value > std::numeric_limits<int>::max()) {
    throw Error(Format(where, ": '", token, "' is out of range (not a 32-bit integer)"));
  }
  return static_cast<int>(value);
}

fs::path TemporaryPathFor(const fs::path& path) {
  fs::path tmp = path;
  tmp.replace_filename(
      Format(path.stem().string(), ".tmp-", ::getpid(), path.extension().string()));
  return tmp;
}

void WriteFileAtomically(const fs::path& path, const std::function<void(const fs::path&)>& write) {
  std::error_code ec;
  if (path.has_parent_path()) {
    fs::create_directories(path.parent_path(), ec);
    if (ec) {
      throw Error(Format(path.string(), ": cannot create folder ", path.parent_path().string(),
                         " (", ec.message(), ")"));
    }
  }
  const fs::path tmp = TemporaryPathFor(path);
  try {
    write(tmp);
    if (!fs::exists(tmp)) throw Error(Format(path.string(), ": writer produced no file"));
    fs::rename(tmp, path, ec);
    if (ec)
      throw Error(
          Format(path.string(), ": cannot rename from ", tmp.string(), " (", ec.message(), ")"));
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
}

void WriteTextFileAtomically(const fs::path& path, const std::string& text) {
  WriteFileAtomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw Error(Format(path.string(), ": cannot write (", std::strerror(errno), ")"));
    out << text;
    out.close();
    if (!out) throw Error(Format(path.string(), ": write failed (disk full?)"));
  });
}

fs::path ResolveRelativeTo(const fs::path& list_file, const std::string& entry) {
  const fs::path p(entry);
  if (p.is_absolute()) return p;
  return list_file.parent_path() / p;
}

uint64_t Fnv1a64(const void* data, size_t size, uint64_t hash) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) {
    hash ^= bytes[i];
    hash *= 1099511628211ull;
  }
  return hash;
}

uint64_t ContentFingerprint(const fs::path& path) {
  std::vector<std::pair<std::string, fs::path>> files;
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    for (auto it = fs::recursive_directory_iterator(path, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      if (it->is_regular_file(ec))
        files.emplace_back(fs::relative(it->path(), path).generic_string(), it->path());
    }
    if (ec) throw Error(Format(path.string(), ": cannot list the folder (", ec.message(), ")"));
    std::sort(files.begin(), files.end());
  } else {
    files.emplace_back("", path);
  }
  uint64_t hash = kFnv1aOffset;
  std::vector<char> buffer(1 << 20);
  for (const auto& [name, file] : files) {
    if (!name.empty()) hash = Fnv1a64(name + '\0', hash);  // a folder's files: path, then bytes
    std::ifstream in(file, std::ios::binary);
    if (!in) throw Error(Format(file.string(), ": cannot read"));
    while (in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      hash = Fnv1a64(buffer.data(), static_cast<size_t>(in.gcount()), hash);
    }
    if (in.bad()) throw Error(Format(file.string(), ": read error"));
  }
  return hash;
}

}  // namespace genscene
