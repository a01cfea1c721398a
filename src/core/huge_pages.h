#pragma once
// Large arrays in transparent huge pages.
//
// The pipeline's arrays run to hundreds of megabytes, and every first touch of
// a 4 KiB page is a page fault; on virtual machines a fault costs several
// microseconds, and faults took a third of the meshing time here
// (docs/performance.md). glibc's malloc asks the kernel for 2 MiB pages
// (madvise MADV_HUGEPAGE) when the tunable glibc.malloc.hugetlb=1 is set, but
// tunables are read only when a process starts. So a program that wants them
// sets the tunable and executes itself again, once, first thing in main.
// Only programs call it (the command line, the benchmarks): re-executing the
// process is no business of a library, and the scalemesh library
// (include/scalemesh/) never does.

namespace scalemesh {

// Sets GLIBC_TUNABLES=glibc.malloc.hugetlb=1 (kept beside any other
// tunables) and re-executes /proc/self/exe with the same arguments, unless the
// tunable is already set, SCALEMESH_HUGE_PAGES=0, or the kernel has
// transparent huge pages switched off. Returns only when it does not
// re-execute (or the exec fails, which leaves the process as it was).
void restart_with_huge_pages(char** argv);

} // namespace scalemesh
