// Reads the CUDA fat binaries embedded in a host binary (executable, object or archive) without the
// CUDA toolkit's cuobjdump (not in the nvcc packages these machines have): every fatbin blob starts
// with the magic 0xBA55ED50; its entries are PTX (kind 1) or ELF cubins (kind 2), each with its SM
// architecture, stored plain or, under nvcc 13's default compress mode once an entry is large enough,
// as a zstd frame (flag 0x8000, decompressed here with libzstd; flag 0x2000 is LZ4, not read). For the
// cubins the function names are read from the ELF section headers (a kernel's code is
// ".text.<mangled>"); for PTX from its ".entry <mangled>(" directives.
// Layout as nvcc 13's fatbinary writes it, checked against the files it produces.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <zstd.h>

namespace sl::test {

struct FatbinContents {
  std::map<int, std::set<std::string>> elf_functions;  // sm -> ".text." section names (mangled)
  std::map<int, std::set<std::string>> ptx_functions;  // compute arch -> kernel entries (mangled)
  std::set<int> ptx_archs;                             // archs with a PTX entry
  int blobs = 0;
};

namespace fatbin_detail {

template <class T>
T rd(const std::vector<char>& d, std::size_t off) {
  T v{};
  if (off + sizeof(T) <= d.size()) std::memcpy(&v, d.data() + off, sizeof(T));
  return v;
}

inline void read_cubin(const std::vector<char>& d, std::size_t base, std::size_t size, std::set<std::string>& out) {
  if (size < 64 || std::memcmp(d.data() + base, "\x7f" "ELF", 4) != 0 || d[base + 4] != 2) return;  // ELF64 only
  const auto shoff = rd<std::uint64_t>(d, base + 0x28);
  const auto shentsize = rd<std::uint16_t>(d, base + 0x3A);
  const auto shnum = rd<std::uint16_t>(d, base + 0x3C);
  const auto shstrndx = rd<std::uint16_t>(d, base + 0x3E);
  if (shoff + std::uint64_t(shnum) * shentsize > size || shstrndx >= shnum) return;
  const std::size_t strsec = base + shoff + std::size_t(shstrndx) * shentsize;
  const auto stroff = rd<std::uint64_t>(d, strsec + 0x18);
  const auto strsize = rd<std::uint64_t>(d, strsec + 0x20);
  if (stroff + strsize > size) return;
  for (std::uint16_t i = 0; i < shnum; ++i) {
    const std::size_t sh = base + shoff + std::size_t(i) * shentsize;
    const auto name = rd<std::uint32_t>(d, sh);
    if (name >= strsize) continue;
    const char* s = d.data() + base + stroff + name;
    const std::string n(s, strnlen(s, std::size_t(strsize - name)));
    if (n.rfind(".text.", 0) == 0) out.insert(n.substr(6));
  }
}

// The kernels a PTX text defines: ".entry NAME(" (".visible .entry", ".entry" of internal linkage).
inline void read_ptx(const char* text, std::size_t size, std::set<std::string>& out) {
  const std::string t(text, strnlen(text, size));
  for (std::size_t at = t.find(".entry "); at != std::string::npos; at = t.find(".entry ", at + 7)) {
    const std::size_t b = at + 7, e = t.find_first_of("( \n", b);
    if (e != std::string::npos && e > b) out.insert(t.substr(b, e - b));
  }
}

// An entry's bytes as stored (plain) or decompressed (one zstd frame; the entry may be padded past
// it); empty when it cannot be read (LZ4, or a frame that does not decode).
inline std::vector<char> entry_bytes(const std::vector<char>& d, std::size_t at, std::size_t size, std::uint64_t flags) {
  if ((flags & 0x2000u) != 0) return {};
  if ((flags & 0x8000u) == 0) return std::vector<char>(d.begin() + std::ptrdiff_t(at), d.begin() + std::ptrdiff_t(at + size));
  const char* src = d.data() + at;
  const std::size_t frame = ZSTD_findFrameCompressedSize(src, size);
  const unsigned long long out_size = ZSTD_getFrameContentSize(src, size);
  if (ZSTD_isError(frame) || out_size == ZSTD_CONTENTSIZE_ERROR || out_size == ZSTD_CONTENTSIZE_UNKNOWN ||
      out_size >= (1ull << 32)) {
    return {};
  }
  std::vector<char> out(static_cast<std::size_t>(out_size));
  const std::size_t n = ZSTD_decompress(out.data(), out.size(), src, frame);
  out.resize(ZSTD_isError(n) ? 0 : n);
  return out;
}

}  // namespace fatbin_detail

inline FatbinContents read_fatbins(const std::string& path) {
  using namespace fatbin_detail;
  std::ifstream f(path, std::ios::binary);
  const std::vector<char> d((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  FatbinContents c;
  const char magic[4] = {char(0x50), char(0xED), char(0x55), char(0xBA)};
  for (std::size_t i = 0; i + 16 <= d.size(); ++i) {
    if (std::memcmp(d.data() + i, magic, 4) != 0) continue;
    const auto version = rd<std::uint16_t>(d, i + 4);
    const auto header = rd<std::uint16_t>(d, i + 6);
    const auto fat_size = rd<std::uint64_t>(d, i + 8);
    if (version != 1 || header != 16 || i + header + fat_size > d.size()) continue;
    ++c.blobs;
    std::size_t p = i + header;
    const std::size_t end = p + fat_size;
    while (p + 64 <= end) {
      const auto kind = rd<std::uint16_t>(d, p);
      const auto entry_header = rd<std::uint32_t>(d, p + 4);
      const auto size = rd<std::uint64_t>(d, p + 8);
      const auto arch = rd<std::uint32_t>(d, p + 28);
      const auto flags = rd<std::uint64_t>(d, p + 40);
      if (entry_header < 64 || p + entry_header + size > end) break;
      const std::vector<char> bytes = entry_bytes(d, p + entry_header, std::size_t(size), flags);
      if (kind == 1) {
        c.ptx_archs.insert(int(arch));
        std::set<std::string>& fns = c.ptx_functions[int(arch)];
        if (bytes.empty()) {
          fns.insert("<compressed>");
        } else {
          read_ptx(bytes.data(), bytes.size(), fns);
        }
      }
      if (kind == 2) {
        std::set<std::string>& fns = c.elf_functions[int(arch)];
        if (bytes.empty()) {
          fns.insert("<compressed>");
        } else {
          read_cubin(bytes, 0, bytes.size(), fns);
        }
      }
      p += entry_header + size;
    }
    i = end - 1;
  }
  return c;
}

}  // namespace sl::test
