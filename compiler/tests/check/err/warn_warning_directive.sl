// expect: W0008
// An active #warning directive prints its message as a warning and
// compilation continues.
#warning "this shader is deprecated; use plastic instead"

surface warn_warning_directive()
{
    Ci = Cs;
    Oi = Os;
}
