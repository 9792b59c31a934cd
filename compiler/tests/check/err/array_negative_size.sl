// expect: E0130
// An array size must be a positive constant; -1 is not.
surface array_negative_size()
{
    float weights[-1];
    weights[0] = 1;
    Ci = Cs * weights[0];
    Oi = Os;
}
