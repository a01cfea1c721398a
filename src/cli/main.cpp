#include "core/version.h"
#include <cstdio>
int main() { std::puts("scalemesh " SCALEMESH_VERSION); return 0; }
