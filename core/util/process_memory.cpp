#include "core/util/process_memory.h"

#include <unistd.h>

#include <fstream>
#include <limits>
#include <string>

namespace sl {
namespace {

double status_mb(const char* field, const char* file = "/proc/self/status") {
  std::ifstream in(file);
  std::string key;
  while (in >> key) {
    if (key == field) {
      double kb = 0;
      in >> kb;
      return kb / 1024.0;
    }
    in.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  }
  return 0.0;
}

}  // namespace

double resident_mb() { return status_mb("VmRSS:"); }
double peak_resident_mb() { return status_mb("VmHWM:"); }

double available_memory_mb() {
  if (const double mb = status_mb("MemAvailable:", "/proc/meminfo"); mb > 0) return mb;
  const long pages = ::sysconf(_SC_AVPHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  return pages > 0 && page > 0 ? double(pages) * double(page) / double(1 << 20) : 0.0;
}

}  // namespace sl
