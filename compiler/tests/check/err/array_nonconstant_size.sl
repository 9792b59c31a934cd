// expect: E0130
// An array size must be a constant; "count" is a variable.
surface array_nonconstant_size()
{
    float count = 3;
    float weights[count];
    weights[0] = count;
    Ci = Cs * weights[0];
    Oi = Os;
}
