// expect: E0136
// A shader parameter's default must be uniform; the global s varies over
// the surface, so it cannot be the default of k.
surface param_default_varying(float k = s;)
{
    Ci = Cs * k;
    Oi = Os;
}
