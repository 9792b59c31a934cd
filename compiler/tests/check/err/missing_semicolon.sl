// expect: E0030
// Syntax error: the declaration of Nf is not terminated by a semicolon.
surface missing_semicolon()
{
    normal Nf = faceforward(normalize(N), I)
    Ci = Cs * diffuse(Nf);
    Oi = Os;
}
