#include "core/memory_text.h"

#include <cmath>
#include <cstdio>

namespace scalemesh {

std::string memory_text(double bytes)
{
    char text[64];
    if (!std::isfinite(bytes) || bytes >= 0x1p40) std::snprintf(text, sizeof text, "%.3g TiB", bytes / 0x1p40);
    else if (bytes >= 0x1p30) std::snprintf(text, sizeof text, "%.3g GiB", bytes / 0x1p30);
    else std::snprintf(text, sizeof text, "%.3g MiB", bytes / 0x1p20);
    return text;
}

} // namespace scalemesh
