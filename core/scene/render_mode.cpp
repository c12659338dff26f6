#include "core/scene/render_mode.h"

#include "core/util/error.h"

namespace sl {

RenderMode parse_render_mode(const std::string& s) {
  if (s == "dvr") return RenderMode::Dvr;
  if (s == "mip") return RenderMode::Mip;
  if (s == "iso") return RenderMode::Iso;
  if (s == "labels") return RenderMode::Labels;
  throw InputError("--mode", "unknown mode '" + s + "' (expected dvr, mip, iso or labels)");
}

SkipMethod parse_skip_method(const std::string& s) {
  if (s == "none") return SkipMethod::None;
  if (s == "bbox") return SkipMethod::BBox;
  if (s == "octree") return SkipMethod::Octree;
  if (s == "sparseleap") return SkipMethod::SparseLeap;
  throw InputError("--method", "unknown method '" + s + "' (expected none, bbox, octree or sparseleap)");
}

IsoMethod parse_iso_method(const std::string& s) {
  if (s == "exact") return IsoMethod::Exact;
  if (s == "sampled") return IsoMethod::Sampled;
  throw InputError("--iso-method", "unknown iso method '" + s + "' (expected exact or sampled)");
}

Filter parse_filter(const std::string& s) {
  if (s == "linear") return Filter::Linear;
  if (s == "quadratic") return Filter::Quadratic;
  if (s == "cubic") return Filter::Cubic;
  throw InputError("--filter", "unknown filter '" + s + "' (expected linear, quadratic or cubic)");
}

const char* to_string(Filter f) {
  switch (f) {
    case Filter::Linear: return "linear";
    case Filter::Quadratic: return "quadratic";
    case Filter::Cubic: return "cubic";
  }
  return "?";
}

const char* to_string(IsoMethod m) {
  switch (m) {
    case IsoMethod::Exact: return "exact";
    case IsoMethod::Sampled: return "sampled";
  }
  return "?";
}

const char* to_string(RenderMode m) {
  switch (m) {
    case RenderMode::Dvr: return "dvr";
    case RenderMode::Mip: return "mip";
    case RenderMode::Iso: return "iso";
    case RenderMode::Labels: return "labels";
  }
  return "?";
}

const char* to_string(SkipMethod m) {
  switch (m) {
    case SkipMethod::None: return "none";
    case SkipMethod::BBox: return "bbox";
    case SkipMethod::Octree: return "octree";
    case SkipMethod::SparseLeap: return "sparseleap";
  }
  return "?";
}

}  // namespace sl
