// expect: E0115
// The second parameter of "split" is an output, so the argument must be a
// variable that can be written, not the expression a + b.
void split(float x; output float half)
{
    half = x / 2;
}

surface output_arg_not_variable()
{
    float a = .25, b = .5;
    split(1, a + b);
    Ci = Cs * (a + b);
    Oi = Os;
}
