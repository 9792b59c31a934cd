// expect: W0007
// bake3d() (point-cloud baking) is accepted but not supported by rtsl: it
// does nothing at run time and the compiler warns.
surface warn_bake3d_unsupported()
{
    normal Nf = faceforward(normalize(N), I);
    float occ = occlusion(P, Nf, 16);
    bake3d("occlusion.ptc", "", P, Nf, "occ", occ);
    Ci = Cs * (1 - occ);
    Oi = Os;
}
