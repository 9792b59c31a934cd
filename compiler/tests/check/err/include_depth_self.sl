// expect: E0002
// include/self_include.h includes itself and has no include guard, so the
// nesting of #include exceeds the preprocessor's depth limit.
#include "include/self_include.h"

surface include_depth_self()
{
    Ci = Cs;
    Oi = Os;
}
