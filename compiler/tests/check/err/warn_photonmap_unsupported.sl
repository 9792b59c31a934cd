// expect: W0007
// photonmap() lookups are accepted but not supported by rtsl: they return
// black at run time and the compiler warns.
surface warn_photonmap_unsupported()
{
    normal Nf = faceforward(normalize(N), I);
    color caustics = photonmap("caustic.pmap", P, Nf);
    Ci = Cs * (diffuse(Nf) + caustics);
    Oi = Os;
}
