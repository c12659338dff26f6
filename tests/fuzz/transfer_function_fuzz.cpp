// Transfer-function JSON (core/scene/transfer_function.cpp): parsed; what parses is written back and must
// read back to the same points (the viewer saves what it loaded), and its tables are looked up.
#include <cmath>
#include <limits>

#include "core/util/error.h"
#include "core/scene/transfer_function.h"
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) {
  const auto parsed = sl::fuzz::accepted([&] { return sl::parse_transfer_function(std::string(input), "tf.json"); });
  if (!parsed) return;
  const sl::TransferFunction& tf = *parsed;
  const sl::TransferFunction back = sl::parse_transfer_function(sl::transfer_function_to_json(tf), "written");
  if (back.points().size() != tf.points().size()) std::abort();
  for (std::size_t i = 0; i < tf.points().size(); ++i) {
    if (back.points()[i].value != tf.points()[i].value || back.points()[i].rgba != tf.points()[i].rgba) std::abort();
  }
  const float inf = std::numeric_limits<float>::infinity();
  const float probes[] = {tf.vmin(), tf.vmax(), 0.5f * tf.vmin() + 0.5f * tf.vmax(), -inf, inf, std::nanf("")};
  const sl::TransferFunctionView v = tf.view(0.5f);
  for (const float p : probes) {
    const sl::vec4 c = v.lookup(p);
    if (!(c.w >= 0.0f && c.w <= 1.0f)) std::abort();
    tf.max_opacity(p, tf.vmax());
  }
}
