#include "cache/formats/zarr/v3_codec.h"

#include <nlohmann/json.hpp>

#include "cache/formats/zarr/codecs/codec.h"

namespace sl::zarr::v3 {
namespace {

using json = nlohmann::json;
using codecs::fail;
using codecs::shape_text;

const json& config(const json& codec) {
  static const json kEmptyObject = json::object();
  if (!codec.contains("configuration")) return kEmptyObject;
  if (!codec["configuration"].is_object()) fail("codec configuration must be an object");
  return codec["configuration"];
}

// "codec 'x' is not supported (transpose, bytes, ...)".
std::string unsupported(const std::string& name) {
  std::string known;
  for (const codecs::Codec& c : codecs::all()) known += (known.empty() ? "" : ", ") + std::string(c.name);
  return "codec '" + name + "' is not supported (" + known + ")";
}

// The chain-order rules (codecs::Role): what has been seen so far decides where the next codec may stand.
struct Placement {
  bool have_bytes = false, have_compressor = false;

  void place(const codecs::Codec& c, std::size_t codec_count, bool sharding_allowed) {
    const std::string name(c.name);
    switch (c.role) {
      case codecs::Role::ArrayToArray:
        if (have_bytes) fail(name + " after the array->bytes codec");
        break;
      case codecs::Role::ArrayToBytes:
        if (have_bytes) fail("two array->bytes codecs");
        have_bytes = true;
        break;
      case codecs::Role::Sharding:
        if (!sharding_allowed) fail("nested " + name + " is not supported");
        if (codec_count != 1) fail(name + " must be the only codec of the array (others go inside the shard)");
        have_bytes = true;
        break;
      case codecs::Role::Checksum:
        if (!have_bytes) fail(name + " before the array->bytes codec");
        break;
      case codecs::Role::Compressor:
        if (!have_bytes) fail(name + " before the array->bytes codec");
        if (have_compressor) fail("two compressors in one chain are not supported");
        have_compressor = true;
        break;
    }
  }
};

}  // namespace

int stored_size(Stored s) {
  switch (s) {
    case Stored::U8: return 1;
    case Stored::U16: case Stored::I16: return 2;
    case Stored::U32: case Stored::F32: return 4;
  }
  return 1;
}

Chain parse_chain(const json& codec_list, const std::vector<std::int64_t>& chunk, int elem, std::optional<Sharding>* shard) {
  if (!codec_list.is_array() || codec_list.empty()) fail("\"codecs\" must be a non-empty list");
  Chain ch;
  Placement placement;
  const codecs::ChainShape shape{chunk, elem, shard};
  for (const json& c : codec_list) {
    if (!c.is_object() || !c.contains("name") || !c["name"].is_string()) fail("every codec needs a string \"name\"");
    const std::string name = c["name"].get<std::string>();
    const json& cfg = config(c);
    const codecs::Codec* codec = codecs::find(name);
    if (!codec) fail(unsupported(name));
    placement.place(*codec, codec_list.size(), shard != nullptr);
    const std::string part = codec->parse(cfg, shape, ch);
    ch.text += (ch.text.empty() ? "" : ", ") + part;
  }
  if (!placement.have_bytes) fail("no array->bytes codec (bytes or sharding_indexed)");
  return ch;
}

std::string ArrayCodecs::key(const std::vector<std::int64_t>& g) const {
  std::string k = default_keys ? "c" : "";
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (i > 0 || default_keys) k += separator;
    k += std::to_string(g[i]);
  }
  if (!default_keys && g.empty()) k = "0";
  return k;
}

std::string ArrayCodecs::describe() const {
  return (shard ? "shards " + shape_text(grid) + ", " : std::string()) + chain.text + ", keys " +
         (default_keys ? "default" : "v2") + " '" + separator + "'";
}

}  // namespace sl::zarr::v3
