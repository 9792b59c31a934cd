// expect: E0109
// L is read-only in surface shaders: light shaders set it, surfaces read it
// inside illuminance loops.
surface write_L_in_surface()
{
    L = vector(0, 1, 0);
    Ci = Cs * diffuse(faceforward(normalize(N), I));
    Oi = Os;
}
