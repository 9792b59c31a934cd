/*
 * exposure_gamma.sl -- photographic exposure (in stops) and display
 * gamma, plus a white-balance tint, applied to the final pixel.  Reports
 * its settings once with a formatted message.
 *
 * Exercises: an imager shader, pow() applied per channel with comp()
 * building a color(r, g, b), format() with %f and %c on uniform
 * arguments, printf(), rendererinfo("version") into a float array,
 * uniform locals, the stringifying SHOWFLOAT macro, and division of
 * colours.
 */
#include "config.h"

imager exposure_gamma(
    float exposure = 0;
    float gamma = 2.2;
    color whitebalance = color(1, 1, 1);
    float report = 0;)
{
    uniform float gain = pow(2, exposure);
    uniform float invgamma = 1 / max(gamma, .01);
    uniform float version[4] = {0, 0, 0, 0};
    uniform string settings = format("exposure %f stops, gamma %f, white %c",
                                     exposure, gamma, whitebalance);

    if (report > 0) {
        rendererinfo("version", version);
        printf("%s (renderer %f.%f)\n", settings, version[0], version[1]);
        SHOWFLOAT(gain);
    }

    color c = Ci * gain / whitebalance;
    Ci = color(pow(max(comp(c, 0), 0), invgamma),
               pow(max(comp(c, 1), 0), invgamma),
               pow(max(comp(c, 2), 0), invgamma));
}
