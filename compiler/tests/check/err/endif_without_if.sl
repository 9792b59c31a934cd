// expect: E0004
// A stray #endif with no #if, #ifdef or #ifndef open.
surface endif_without_if()
{
    Ci = Cs;
    Oi = Os;
}
#endif
