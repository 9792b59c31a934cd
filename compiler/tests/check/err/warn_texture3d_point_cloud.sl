// expect: W0007
// texture3d() with a normal is PRMan's point-cloud lookup, which rtsl does
// not support: it returns 0 at run time and the compiler warns.  The grid
// form, texture3d(file, P) without a normal, is supported (docs/volumes.md).
surface warn_texture3d_point_cloud()
{
    normal Nf = faceforward(normalize(N), I);
    float baked = texture3d("bake.ptc", P, Nf);
    float grid = texture3d("density.grid", P);
    Ci = Cs * (baked + grid);
    Oi = Os;
}
