/*
 * shadowdistant.sl -- a directional light with a shadow map, for
 * daylight scenes: the light has a small angular spread so surfaces near
 * the terminator are lit smoothly, and the shadow can be tinted.
 *
 * Exercises: solar(axis, angle) with a non-zero spread angle, shadow()
 * with the plain two-argument form and with "blur", radians(), uniform
 * vector locals, the __nondiffuse output parameter, and a string
 * parameter test.
 */
light shadowdistant(
    float intensity = 1;
    color lightcolor = 1;
    point from = point "shader" (0, 0, 0);
    point to = point "shader" (0, 0, 1);
    float spread = 0.5;
    string shadowname = "";
    float shadowblur = 0;
    color shadowtint = color(.1, .1, .2);
    output uniform float __nondiffuse = 0;)
{
    uniform vector dir = to - from;
    uniform float spreadrad = radians(spread);

    solar(dir, spreadrad) {
        float shad = 0;
        if (shadowname != "") {
            if (shadowblur > 0)
                shad = shadow(shadowname, Ps, "blur", shadowblur);
            else
                shad = shadow(shadowname, Ps);
        }
        Cl = intensity * mix(lightcolor, shadowtint * lightcolor, shad);
    }
}
