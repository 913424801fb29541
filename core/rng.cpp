#include "core/rng.h"

#include <cmath>

namespace genscene {

double CounterRng::Normal() {
  // 1 - U is in (0, 1], so the log is finite.
  const double u1 = 1.0 - UniformDouble();
  const double u2 = UniformDouble();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace genscene
