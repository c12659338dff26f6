// The process's resident memory, from /proc/self/status (Linux): what bench's soak reports and
// the distributed driver's per-rank figures; and the memory the machine has available for a budget.
#pragma once

namespace sl {

// Current resident set (VmRSS) in MB; 0 where /proc is missing.
double resident_mb();
// Peak resident set (VmHWM) in MB; 0 where /proc is missing.
double peak_resident_mb();
// Memory available to a new allocation in MB: MemAvailable of /proc/meminfo (free memory plus the
// caches the kernel can drop), else the free physical pages (sysconf); 0 when neither is known.
double available_memory_mb();

}  // namespace sl
