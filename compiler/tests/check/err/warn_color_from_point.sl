// expect: W0009
// A point is assigned to a color without a cast; the components are
// copied as-is, with a warning.  Write color(xcomp(P), ycomp(P), zcomp(P)).
surface warn_color_from_point()
{
    color c = P;
    Ci = Cs * c;
    Oi = Os;
}
