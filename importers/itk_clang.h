#pragma once
// Force-included into the importers under clang (the fuzz and sanitizer
// builds, importers/CMakeLists.txt). Debian's ITK 5.2
// headers were generated for GCC only: itk_compiler_detection.h stops with
// "Unsupported compiler" under clang. It is read here once as under GCC 12
// (clang 14 in C++20 has every feature its table lists for GCC); its include
// guard then keeps ITK's own include of it from reading it again.
#pragma push_macro("__clang__")
#pragma push_macro("__GNUC__")
#pragma push_macro("__GNUC_MINOR__")
#undef __clang__
#undef __GNUC__
#undef __GNUC_MINOR__
#define __GNUC__ 12
#define __GNUC_MINOR__ 2
#include <itk_compiler_detection.h>
#pragma pop_macro("__GNUC_MINOR__")
#pragma pop_macro("__GNUC__")
#pragma pop_macro("__clang__")
