// expect: E0118
// "foo" is not a colour space (rgb, hsv, hsl, xyz, XYZ, xyY, YIQ).
surface unknown_colorspace()
{
    color c = color "foo" (1, 0, 0);
    Ci = Cs * c;
    Oi = Os;
}
