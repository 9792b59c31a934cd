// expect: E0105
// The user function "brighten" takes two arguments but is called with three.
color brighten(color c; float amount)
{
    return c * (1 + amount);
}

surface user_func_argc()
{
    Ci = brighten(Cs, .5, 2);
    Oi = Os;
}
