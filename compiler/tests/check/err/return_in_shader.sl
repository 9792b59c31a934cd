// expect: E0116
// A shader body has no return value, so "return 1;" is not allowed in it.
surface return_in_shader(float Kd = 1;)
{
    Oi = Os;
    Ci = Cs * Kd;
    if (Kd > 0)
        return 1;
}
