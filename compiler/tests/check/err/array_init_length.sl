// expect: E0124
// The array has three elements but its initialiser lists only two.
surface array_init_length()
{
    float weights[3] = {1, 2};
    Ci = Cs * (weights[0] + weights[1] + weights[2]);
    Oi = Os;
}
