#include "core/check.h"

namespace genscene::detail {

void ThrowCheckFailure(const char* file, int line, const std::string& what) {
  throw Error(StrCat(what, " at ", file, ":", line));
}

}  // namespace genscene::detail
