/*
 * sky_fill.sl -- a soft sky fill: either light from all directions
 * (solar() with no arguments) or from a wide cone around "up", tinted
 * from horizon to zenith, with its specular contribution dialled by a
 * parameter that is turned into the __nonspecular message at run time.
 *
 * Exercises: solar() with no arguments and solar(axis, angle) chosen by
 * a uniform float, assigning output uniform message parameters
 * (__nonspecular, __nondiffuse) in the shader body from other
 * parameters, a comma-separated __category list, vtransform of an
 * "up" vector from "world", normalize(-L) dot products inside solar,
 * mix() of colours by a varying factor, and surface("Kd", v) read
 * from the light.
 */
light sky_fill(
    float intensity = 0.3;
    color zenithcolor = color(0.45, 0.6, 1), horizoncolor = color(0.85, 0.9, 1);
    float omni = 0;
    float coneangle = 80;
    float specularity = 0;
    float diffusity = 1;
    uniform string __category = "fill,sky";
    output uniform float __nonspecular = 1;
    output uniform float __nondiffuse = 0;)
{
    __nonspecular = 1 - clamp(specularity, 0, 1);
    __nondiffuse = (diffusity > 0) ? 0 : 1;

    uniform vector up = normalize(vtransform("world", "current", vector(0, 1, 0)));

    /* Darker surfaces get a touch more fill so they do not go flat black. */
    float kd = 1;
    surface("Kd", kd);
    float boost = 1 / max(0.25, kd);

    if (omni != 0) {
        solar() {
            Cl = intensity * boost * mix(horizoncolor, zenithcolor, 0.5);
        }
    } else {
        solar(-up, radians(coneangle)) {           /* light flows down from the sky */
            /* L is the direction of flow; -L points back up at the sky. */
            float elevation = clamp(normalize(-L) . up, 0, 1);
            Cl = intensity * boost * mix(horizoncolor, zenithcolor, elevation);
        }
    }
}
