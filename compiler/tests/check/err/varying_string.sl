// expect: E0129
// Strings are always uniform; a string variable cannot be declared varying.
surface varying_string()
{
    varying string label = "a";
    printf("%s\n", label);
    Ci = Cs;
    Oi = Os;
}
