// expect: E0001
// The header named in #include does not exist in the including file's
// directory or on any include path.
#include "no_such_header.h"

surface include_not_found()
{
    Ci = Cs;
    Oi = Os;
}
