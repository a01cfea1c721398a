#include "core/huge_pages.h"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <string>

namespace scalemesh {

void restart_with_huge_pages(char** argv)
{
    constexpr const char* kTunable = "glibc.malloc.hugetlb";
    const char* opt_out = std::getenv("SCALEMESH_HUGE_PAGES");
    if (opt_out && std::string(opt_out) == "0") return;
    const char* tunables = std::getenv("GLIBC_TUNABLES");
    const std::string current = tunables ? tunables : "";
    if (current.find(kTunable) != std::string::npos) return;
    // "always [madvise] never": huge pages on request; "[never]": none to ask for.
    std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
    std::string modes;
    std::getline(thp, modes);
    if (modes.find("[never]") != std::string::npos || modes.empty()) return;
    const std::string value = (current.empty() ? "" : current + ":") + kTunable + "=1";
    if (::setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
    ::execv("/proc/self/exe", argv);
    // The exec failed: carry on as we are, without the tunable in the way of a later attempt.
    if (tunables) ::setenv("GLIBC_TUNABLES", current.c_str(), 1);
    else ::unsetenv("GLIBC_TUNABLES");
}

} // namespace scalemesh
