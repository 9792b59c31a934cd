// A header that includes itself with no include guard, so a preprocessor
// that follows it recurses until it hits its include depth limit.
// Used by ../include_depth_self.sl.
#include "self_include.h"
#define SELF_INCLUDE_SEEN 1
