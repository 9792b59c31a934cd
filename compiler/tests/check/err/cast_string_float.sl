// expect: E0127
// A float cannot be typecast to a string.
surface cast_string_float()
{
    string label = string 1;
    printf("%s\n", label);
    Ci = Cs;
    Oi = Os;
}
