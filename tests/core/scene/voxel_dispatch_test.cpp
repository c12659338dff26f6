// dispatch_voxel / dispatch_label: each run-time type reaches the right element type, results come
// back unchanged, and float labels go to the caller's handler.
#include <gtest/gtest.h>

#include <string>
#include <type_traits>

#include "core/util/error.h"
#include "core/scene/volume.h"
#include "core/scene/voxel_dispatch.h"

namespace sl {
namespace {

template <class T> constexpr const char* type_name() {
  if constexpr (std::is_same_v<T, std::uint8_t>) return "u8";
  if constexpr (std::is_same_v<T, std::uint16_t>) return "u16";
  if constexpr (std::is_same_v<T, std::uint32_t>) return "u32";
  if constexpr (std::is_same_v<T, float>) return "f32";
  return "?";
}

TEST(VoxelDispatch, EachTypeReachesItsElementType) {
  for (VoxelType t : {VoxelType::U8, VoxelType::U16, VoxelType::U32, VoxelType::F32}) {
    const std::string name = dispatch_voxel(t, [](auto tag) { return std::string(type_name<decltype(tag)>()); });
    EXPECT_EQ(name, to_string(t));
    const int size = dispatch_voxel(t, [](auto tag) { return int(sizeof(tag)); });
    EXPECT_EQ(size, voxel_size(t));
  }
}

TEST(VoxelDispatch, ReturnsReferencesAsReferences) {
  int a = 1;
  int& r = dispatch_voxel(VoxelType::U16, [&](auto) -> int& { return a; });
  r = 5;
  EXPECT_EQ(a, 5);
}

TEST(VoxelDispatch, LabelsAreIntegerTypesAndFloatIsTheCallersError) {
  for (VoxelType t : {VoxelType::U8, VoxelType::U16, VoxelType::U32}) {
    const std::string name = dispatch_label(
        t, [](auto tag) { return std::string(type_name<decltype(tag)>()); },
        []() -> std::string { throw InputError("labels", "not reached"); });
    EXPECT_EQ(name, to_string(t));
  }
  EXPECT_THROW(dispatch_label(
                   VoxelType::F32, [](auto) {}, [] { throw InputError("--labels", "must be an integer type"); }),
               InputError);
  EXPECT_EQ(dispatch_label(VoxelType::F32, [](auto tag) { return int(sizeof(tag)); }, [] { return -1; }), -1);
}

TEST(VoxelDispatch, VolumeReadsAndWritesEveryType) {
  for (VoxelType t : {VoxelType::U8, VoxelType::U16, VoxelType::U32, VoxelType::F32}) {
    Volume v(VolumeDesc{ivec3(3, 2, 2), vec3(1.0f), t});
    v.set(1, 1, 1, 200.4f);
    v.set(0, 0, 0, -3.0f);
    v.set(2, 0, 1, 1e6f);
    const bool f = t == VoxelType::F32;
    EXPECT_EQ(v.value(1, 1, 1), f ? 200.4f : 200.0f) << to_string(t);
    EXPECT_EQ(v.value(0, 0, 0), f ? -3.0f : 0.0f) << to_string(t);  // integers clamp at 0
    const float big = t == VoxelType::U8 ? 255.0f : t == VoxelType::U16 ? 65535.0f : 1e6f;
    EXPECT_EQ(v.value(2, 0, 1), big) << to_string(t);
    EXPECT_EQ(v.label(1, 1, 1), 200u) << to_string(t);
  }
}

}  // namespace
}  // namespace sl
