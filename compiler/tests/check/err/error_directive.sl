// expect: E0009
// An active #error directive stops compilation with its message.
#ifndef NEEDS_FEATURE_X
#error "this shader must be compiled with -DNEEDS_FEATURE_X"
#endif

surface error_directive()
{
    Ci = Cs;
    Oi = Os;
}
