// The `transpose` codec (array->array): the chunk's axes stored in another order.
#include <cstring>
#include <nlohmann/json.hpp>

#include "cache/formats/zarr/codecs/codec.h"

namespace sl::zarr::v3::codecs {

std::string parse_transpose(const nlohmann::json& config, const ChainShape& shape, Chain& chain) {
  const std::size_t nd = shape.chunk.size();
  if (!config.contains("order") || !config["order"].is_array() || config["order"].size() != nd) {
    fail("transpose \"order\" must list " + std::to_string(nd) + " axes");
  }
  std::vector<int> t;
  std::vector<bool> seen(nd, false);
  for (const nlohmann::json& o : config["order"]) {
    if (!o.is_number_integer() || o.get<long long>() < 0 || o.get<long long>() >= (long long)nd ||
        seen[o.get<std::size_t>()]) {
      fail("transpose \"order\" must be a permutation of 0.." + std::to_string(nd - 1));
    }
    seen[o.get<std::size_t>()] = true;
    t.push_back(o.get<int>());
  }
  // Two transposes compose: encoded axis j of the second is decoded axis first[second[j]].
  if (!chain.transpose.empty()) {
    for (int& a : t) a = chain.transpose[std::size_t(a)];
  }
  chain.transpose = t;
  return "transpose";
}

std::vector<std::byte> untranspose(const std::vector<std::byte>& in, const std::vector<int>& order,
                                   const std::vector<std::int64_t>& shape, int elem) {
  // Walks the encoded array in C order, placing each element at its decoded offset.
  const std::size_t n = element_count(shape), nd = shape.size();
  std::vector<std::size_t> dstride(nd, 1), step(nd), es(nd), e(nd, 0);
  for (std::size_t i = nd - 1; i-- > 0;) dstride[i] = dstride[i + 1] * std::size_t(shape[i + 1]);
  for (std::size_t i = 0; i < nd; ++i) {
    es[i] = std::size_t(shape[std::size_t(order[i])]);
    step[i] = dstride[std::size_t(order[i])];
  }
  std::vector<std::byte> out(in.size());
  std::size_t off = 0;
  for (std::size_t k = 0; k < n; ++k) {
    std::memcpy(out.data() + off * std::size_t(elem), in.data() + k * std::size_t(elem), std::size_t(elem));
    for (std::size_t i = nd; i-- > 0;) {
      off += step[i];
      if (++e[i] < es[i]) break;
      off -= step[i] * es[i];
      e[i] = 0;
    }
  }
  return out;
}

}  // namespace sl::zarr::v3::codecs
