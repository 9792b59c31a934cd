// expect: W0003
// Assigning a color to a float narrows it (only one channel, or an
// average, survives); the compiler warns.  Use comp() or a luminance sum.
surface warn_narrowing_color()
{
    float f = Cs;
    Ci = f * Cs;
    Oi = Os;
}
