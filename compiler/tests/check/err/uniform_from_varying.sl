// expect: E0110
// noise(P) varies over the surface, so it cannot initialise a variable
// declared uniform.
surface uniform_from_varying()
{
    uniform float n = noise(P);
    Ci = Cs * n;
    Oi = Os;
}
