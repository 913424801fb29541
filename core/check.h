// Error policy shared by every library (DESIGN.md §3, STYLE.md 7).
//
// - Inputs are checked at stage boundaries; failures throw genscene::Error with the concrete
//   values ("depth 640x480 but intrinsics say 320x240"), naming the file or key when there is one.
// - Inside kernels, GS_CHECK_* macros print both operands and the source location.
// - "No result" is a std::optional, never a sentinel value.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace genscene {

// The one exception type of the project. Apps catch it at the top, print what() on one line
// and exit non-zero.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// An error in how a program was called: an unknown flag, a bad option value, a missing argument,
// a config file that cannot be applied. The apps exit 2 on it (1 on every other Error).
class UsageError : public Error {
 public:
  using Error::Error;
};

namespace detail {

// Concatenates any streamable values into one string.
template <typename... Args>
std::string StrCat(const Args&... args) {
  std::ostringstream out;
  (out << ... << args);
  return out.str();
}

[[noreturn]] void ThrowCheckFailure(const char* file, int line, const std::string& what);

}  // namespace detail

// Builds an Error message from streamable parts: throw Error(Format("bad ", x)).
template <typename... Args>
std::string Format(const Args&... args) {
  return detail::StrCat(args...);
}

}  // namespace genscene

// GS_CHECK(cond) << nothing: plain condition check with the expression in the message.
#define GS_CHECK(cond)                                                                          \
  do {                                                                                          \
    if (!(cond)) ::genscene::detail::ThrowCheckFailure(__FILE__, __LINE__, "CHECK(" #cond ")"); \
  } while (0)

// Comparison checks print both operands: "CHECK_EQ(a, b) failed: 3 vs 4".
#define GS_CHECK_OP_(op, name, a, b)                                                           \
  do {                                                                                         \
    const auto& gs_a_ = (a);                                                                   \
    const auto& gs_b_ = (b);                                                                   \
    if (!(gs_a_ op gs_b_))                                                                     \
      ::genscene::detail::ThrowCheckFailure(                                                   \
          __FILE__, __LINE__,                                                                  \
          ::genscene::detail::StrCat(name "(" #a ", " #b ") failed: ", gs_a_, " vs ", gs_b_)); \
  } while (0)

#define GS_CHECK_EQ(a, b) GS_CHECK_OP_(==, "CHECK_EQ", a, b)
#define GS_CHECK_NE(a, b) GS_CHECK_OP_(!=, "CHECK_NE", a, b)
#define GS_CHECK_LT(a, b) GS_CHECK_OP_(<, "CHECK_LT", a, b)
#define GS_CHECK_LE(a, b) GS_CHECK_OP_(<=, "CHECK_LE", a, b)
#define GS_CHECK_GT(a, b) GS_CHECK_OP_(>, "CHECK_GT", a, b)
#define GS_CHECK_GE(a, b) GS_CHECK_OP_(>=, "CHECK_GE", a, b)
