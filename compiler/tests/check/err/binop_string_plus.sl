// expect: E0106
// The + operator is not defined between a string and a float.
surface binop_string_plus(string label = "a";)
{
    printf("%s\n", label + 1);
    Ci = Cs;
    Oi = Os;
}
