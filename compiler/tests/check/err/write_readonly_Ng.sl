// expect: E0109
// Ng (the geometric normal) is read-only in a surface shader.
surface write_readonly_Ng()
{
    Ng = N;
    Ci = Cs * diffuse(faceforward(normalize(N), I));
    Oi = Os;
}
