// expect: E0104
// noise() has no overload taking a string argument.
surface builtin_bad_arg_type()
{
    float n = noise("x");
    Ci = Cs * n;
    Oi = Os;
}
