/*
 * raytraced_point.sl -- a point light with ray-traced shadows: the
 * fraction of light reaching the surface is measured by transmission()
 * (which also colours light passing through tinted glass), and an
 * optional falloff exponent replaces the inverse-square law.
 *
 * Exercises: illuminate(from) without an axis, transmission(Ps, from)
 * with and without optional "samples"/"samplecone" arguments, a float
 * parameter used as a switch, length(L), pow() falloff, and ?: between
 * two colour expressions.
 */
light raytraced_point(
    float intensity = 1;
    color lightcolor = 1;
    point from = point "shader" (0, 0, 0);
    float falloff = 2;
    float castshadows = 1;
    float radius = 0;
    float samples = 1;)
{
    illuminate(from) {
        float dist = length(L);
        float atten = 1 / pow(max(dist, 1.0e-4), falloff);
        color vis = 1;
        if (castshadows > 0) {
            vis = (radius > 0) ? transmission(Ps, from, "samples", samples,
                                              "samplecone", atan(radius / max(dist, radius)))
                               : transmission(Ps, from);
        }
        Cl = intensity * lightcolor * atten * vis;
    }
}
