// expect: W0011
// The #ifdef opened on line 5 is never closed: the file ends before the
// matching #endif. C preprocessors end it there with a warning, and so does
// rtsl: the shader compiles.
#define USE_BLUE 1
#ifdef USE_BLUE
surface if_without_endif()
{
    Ci = color(0, 0, 1);
    Oi = Os;
}
