// expect: E0121
// A source file may define only one shader; this one defines two.
surface first_shader()
{
    Ci = Cs;
    Oi = Os;
}

surface second_shader()
{
    Ci = 1 - Cs;
    Oi = Os;
}
