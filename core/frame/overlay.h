// Views for people drawn into a frame: the depth-complexity image with its legend, and the occupancy
// geometry as a wireframe overlay (EMPTY red, NON_EMPTY green, UNKNOWN grey).
#pragma once

#include <span>
#include <string>

#include "core/scene/camera.h"
#include "core/util/image.h"
#include "core/occupancy/occupancy_geometry.h"

namespace sl {

// Replaces the image's colour by depth complexity (channel "depth_complexity") as brightness, scaled
// to [0, max], and draws a legend (a ramp with "min avg max" numbers) in the bottom-left corner.
void draw_depth_complexity(Image& img, float min_dc, float avg_dc, float max_dc);

// Draws the edges of every box over the image (premultiplied "over" blend), clipped to the eye plane.
void draw_boxes(Image& img, std::span<const OccupancyBox> boxes, const RayGenerator& gen);

// Draws text with a built-in 5x7 pixel font (digits, '.', ' ', and lowercase letters used by legends).
void draw_text(Image& img, int x, int y, const std::string& text, const vec4& color, int scale = 2);

}  // namespace sl
