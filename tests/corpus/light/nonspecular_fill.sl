/*
 * nonspecular_fill.sl -- a soft fill light that only lights the diffuse
 * term (it declares __nonspecular = 1) and that scales itself by the
 * diffuse coefficient of the surface it lights, so very dark surfaces
 * are not flattened by fill.
 *
 * Exercises: illuminate(from), output uniform __nonspecular and
 * __nondiffuse parameters, a __category string, the surface("Kd", kd)
 * message-passing call from a light shader, a distance-based linear
 * falloff with clamp(), and the "fill" category used by surfaces.
 */
light nonspecular_fill(
    float intensity = .3;
    color lightcolor = color(.8, .85, 1);
    point from = point "shader" (0, 0, 0);
    float maxdist = 50;
    float kdcompensate = 1;
    uniform string __category = "fill";
    output uniform float __nonspecular = 1;
    output uniform float __nondiffuse = 0;)
{
    float kd = 1;

    /* Read the surface's own Kd; if it has none, assume 1. */
    if (surface("Kd", kd) == 0)
        kd = 1;
    float compensate = mix(1, 1 / max(kd, .1), kdcompensate);

    illuminate(from) {
        float atten = clamp(1 - length(L) / maxdist, 0, 1);
        Cl = intensity * lightcolor * atten * compensate;
    }
}
