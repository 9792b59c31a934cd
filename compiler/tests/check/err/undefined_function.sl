// expect: E0101
// "normalise" is not a built-in or user function (the built-in is spelled
// "normalize").
surface undefined_function()
{
    normal Nf = faceforward(normalise(N), I);
    Ci = Cs * diffuse(Nf);
    Oi = Os;
}
