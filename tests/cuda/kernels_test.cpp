// The CUDA kernels are in the binaries for every architecture CMake built (SASS for each real
// architecture, PTX for each virtual one: CMakeLists.txt's SL_CUDA_ARCHS), found by reading the
// embedded fat binaries (tests/cuda/fatbin.h; the toolkit's cuobjdump
// is not part of the nvcc packages on these machines). No GPU is needed.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "tests/cuda/fatbin.h"

namespace sl::test {
int shared_headers_kernels();  // shared_headers_compile.cu (nvcc)
}

namespace sl {
namespace {

struct Arch {
  int sm = 0;
  bool ptx = false;  // "90" = SASS + PTX, "90-real" = SASS only, "90-virtual" = PTX only
  bool sass = true;
};

std::vector<Arch> parse_archs(const std::string& list) {
  std::vector<Arch> out;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    Arch a;
    a.sm = std::stoi(item);
    a.ptx = item.find("-real") == std::string::npos;
    a.sass = item.find("-virtual") == std::string::npos;
    out.push_back(a);
  }
  return out;
}

bool has_function(const std::set<std::string>& fns, const std::string& a, const std::string& b) {
  for (const std::string& f : fns) {
    if (f.find(a) != std::string::npos && f.find(b) != std::string::npos) return true;
  }
  return false;
}

std::string list_functions(const std::set<std::string>& fns) {
  std::string s;
  for (const std::string& f : fns) s += "\n  " + f;
  return s;
}

TEST(CudaKernels, EveryMethodAndSamplerIsInTheExecutableForEveryArchitecture) {
  const test::FatbinContents c = test::read_fatbins(SL_SPARSELEAP_EXE);
  ASSERT_GT(c.blobs, 0) << "no CUDA fat binary in " << SL_SPARSELEAP_EXE;
  const std::vector<Arch> archs = parse_archs(SL_CUDA_ARCHS);
  ASSERT_FALSE(archs.empty());
  // Itanium mangling: <length><name>; intensity types h (u8), t (u16), j (u32), f (f32).
  const std::vector<std::string> dense = {"20DenseAnyLabelSamplerIhE", "20DenseAnyLabelSamplerItE",
                                          "20DenseAnyLabelSamplerIjE", "20DenseAnyLabelSamplerIfE"};
  const std::vector<std::string> virt = {"22VirtualAnyLabelSamplerIhE", "22VirtualAnyLabelSamplerItE",
                                         "22VirtualAnyLabelSamplerIjE", "22VirtualAnyLabelSamplerIfE"};
  const std::vector<std::string> tex = {"21TextureVirtualSamplerIhE", "21TextureVirtualSamplerItE",
                                        "21TextureVirtualSamplerIfE"};
  const std::string none = "12sl_cast_none", octree = "14sl_cast_octree", lists = "21sl_cast_segment_lists";
  // Every kernel in the code of every architecture: each SASS (cubin) and each PTX text.
  auto expect_kernels = [&](const std::set<std::string>& fns, const std::string& where) {
    ASSERT_FALSE(fns.count("<compressed>")) << where << ": cannot be decompressed, its kernels not listed";
    for (const std::string& s : dense) {
      for (const std::string& k : {none, octree, lists}) {
        EXPECT_TRUE(has_function(fns, k, s)) << where << ": " << k << " over " << s << list_functions(fns);
      }
    }
    for (const auto* set : {&virt, &tex}) {
      for (const std::string& s : *set) {
        for (const std::string& k : {none, lists}) {
          EXPECT_TRUE(has_function(fns, k, s)) << where << ": " << k << " over " << s;
        }
      }
    }
  };
  for (const Arch& a : archs) {
    if (a.ptx) {
      ASSERT_TRUE(c.ptx_functions.count(a.sm)) << "no PTX for compute_" << a.sm;
      expect_kernels(c.ptx_functions.at(a.sm), "PTX compute_" + std::to_string(a.sm));
    }
    if (a.sass) {
      ASSERT_TRUE(c.elf_functions.count(a.sm)) << "no SASS for sm_" << a.sm;
      expect_kernels(c.elf_functions.at(a.sm), "SASS sm_" + std::to_string(a.sm));
    }
  }
}

TEST(CudaKernels, SharedHeadersCompileUnderNvccIntoDeviceCode) {
  EXPECT_EQ(test::shared_headers_kernels(), 4);
  const test::FatbinContents c = test::read_fatbins("/proc/self/exe");
  // This test binary's own .cu is built for sm_75 only (tests/CMakeLists.txt).
  ASSERT_TRUE(c.elf_functions.count(75));
  const std::set<std::string>& fns = c.elf_functions.at(75);
  EXPECT_TRUE(has_function(fns, "28shared_headers_compile_check", "12DenseSamplerIhhE")) << list_functions(fns);
  EXPECT_TRUE(has_function(fns, "28shared_headers_compile_check", "12DenseSamplerIfjE"));
  EXPECT_TRUE(has_function(fns, "28shared_headers_compile_check", "14VirtualSamplerIttE"));
  EXPECT_TRUE(has_function(fns, "28shared_headers_compile_check", "14VirtualSamplerIfjE"));
}

}  // namespace
}  // namespace sl
