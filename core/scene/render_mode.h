// What a ray computes along its samples (DESIGN.md "Ray casting").
#pragma once

#include <cstdint>
#include <string>

namespace sl {

enum class RenderMode : std::uint8_t { Dvr = 0, Mip = 1, Iso = 2, Labels = 3 };

// Empty-space skipping method; all produce the same image (DESIGN.md "Ray casting": one global sample grid).
enum class SkipMethod : std::uint8_t { None = 0, BBox = 1, Octree = 2, SparseLeap = 3 };

// How iso mode finds the surface (DESIGN.md "Ray casting"): Exact, the first root of the trilinear interpolant per
// cell (core/recon/exact_iso.h, seed 004); Sampled, the first sample pair bracketing the iso value, refined by
// bisection (misses a surface crossed twice within one step).
enum class IsoMethod : std::uint8_t { Exact = 0, Sampled = 1 };

// The reconstruction filter (DESIGN.md "Ray casting"): trilinear, or the uniform tri-quadratic or
// tri-cubic B-spline with the voxels as control points (approximating: smoother than the data). Exact
// iso finds roots of the filter's own ray polynomial (degree 3, 6, 9); DVR, MIP and sampled iso take
// B-spline samples from 8 trilinear fetches [SH05] (core/recon/bspline.h).
enum class Filter : std::uint8_t { Linear = 0, Quadratic = 1, Cubic = 2 };

// Modes whose frames carry a "depth" channel: iso, the ray parameter t of the surface hit; DVR and
// labels, the t at which the accumulated opacity first reaches kDepthOpacity (-1 where it never does).
// MIP has no depth.
inline constexpr float kDepthOpacity = 0.5f;
constexpr bool writes_depth(RenderMode m) { return m != RenderMode::Mip; }

// Parse/print the command-line names; parse throws InputError(option, reason).
RenderMode parse_render_mode(const std::string& s);
SkipMethod parse_skip_method(const std::string& s);
IsoMethod parse_iso_method(const std::string& s);
Filter parse_filter(const std::string& s);
const char* to_string(RenderMode m);
const char* to_string(SkipMethod m);
const char* to_string(IsoMethod m);
const char* to_string(Filter f);

}  // namespace sl
