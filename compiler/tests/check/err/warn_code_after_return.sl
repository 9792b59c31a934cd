// expect: W0004
// The assignment after the return statement can never execute.
float half_of(float x)
{
    float y = x / 2;
    return y;
    y = 0;
}

surface warn_code_after_return()
{
    Ci = Cs * half_of(1);
    Oi = Os;
}
