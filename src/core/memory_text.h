#pragma once
// Byte counts for messages, in the binary units --max-memory reads.

#include <string>

namespace scalemesh {

// "1.25 MiB", "9.31 GiB", "2.5 TiB": three significant digits; beyond a
// thousand TiB (more than any machine holds) in powers of ten of TiB, so the
// unit is never cut off; NaN or infinite as such, in TiB.
std::string memory_text(double bytes);

} // namespace scalemesh
