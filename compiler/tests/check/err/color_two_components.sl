// expect: E0125
// A color constructor takes one or three components, not two.
surface color_two_components()
{
    color tint = color(1, 2);
    Ci = Cs * tint;
    Oi = Os;
}
