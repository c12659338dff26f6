// The process's resident memory, from /proc/self/status (Linux): what bench's soak reports and
// the distributed driver's per-rank figures.
#pragma once

namespace sl {

// Current resident set (VmRSS) in MB; 0 where /proc is missing.
double resident_mb();
// Peak resident set (VmHWM) in MB; 0 where /proc is missing.
double peak_resident_mb();

}  // namespace sl
