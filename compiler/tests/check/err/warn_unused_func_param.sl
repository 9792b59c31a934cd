// expect: W0002
// The parameter "amount" of the user function "tint" is never used.
color tint(color c; float amount)
{
    return c * color(1, .9, .8);
}

surface warn_unused_func_param()
{
    Ci = tint(Cs, .5);
    Oi = Os;
}
