// expect: W0012
// Aqsis's ambient light, as its examples write it: an occlusion map's name first.
light envlight(float intensity = 1; string filename = "occlmap.sm"; float samples = 8;)
{
    float o = occlusion(filename, Ps, Ns, 0, "samples", samples, "bias", 0.01);
    Cl = intensity * (1 - o);
}
