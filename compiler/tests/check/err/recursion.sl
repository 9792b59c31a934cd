// expect: E0114
// "octave" calls itself; the shading language does not allow recursion.
float octave(point p; float n)
{
    return (n <= 0) ? 0 : noise(p) + .5 * octave(p * 2, n - 1);
}

surface recursion()
{
    Ci = Cs * octave(P, 4);
    Oi = Os;
}
