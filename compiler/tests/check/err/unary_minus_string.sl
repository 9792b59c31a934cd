// expect: E0107
// Unary minus cannot be applied to a string.
surface unary_minus_string(string label = "x";)
{
    printf("%s\n", -label);
    Ci = Cs;
    Oi = Os;
}
