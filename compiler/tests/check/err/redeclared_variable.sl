// expect: E0102
// "shade" is declared twice in the same scope.
surface redeclared_variable()
{
    float shade = .5;
    float shade = .75;
    Ci = Cs * shade;
    Oi = Os;
}
