// expect: E0133
// "f" is a float variable, not a function, so it cannot be called.
surface call_variable()
{
    float f = 1;
    Ci = Cs * f(2);
    Oi = Os;
}
