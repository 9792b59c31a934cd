// expect: E0110
// A uniform variable assigned under a varying condition is kept per lane, but it
// still may not take a value that varies over the surface.
surface uniform_kept_per_lane_from_varying()
{
    uniform float k = 0;
    if (t > 0.5)
        k = 2;
    k = s;
    Ci = Cs * k;
    Oi = Os;
}
