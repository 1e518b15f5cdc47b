/* The reader's implementation as a C translation unit (integrations/CMakeLists.txt): what the
 * C++ tests and the differential fuzzer link, so that the code they check is compiled as C. */
#define PROBEKIT_PVOL_IMPLEMENTATION
#include "probekit_pvol.h"
