/*
 * checker_modfloor.sl -- a checkerboard three ways: a plain one from
 * mod() of summed floor()s, a box-filtered one from square-wave
 * integrals, and a blend that switches to the filtered version only
 * when the checks approach the sample size.  Optional debug printing.
 *
 * Exercises: mod(floor(ss) + floor(tt), 2), the filteredchecker()
 * function and SQUAREINT() macro from a header, filterwidth() on s and
 * t, #ifdef DEBUG_CHECKER around printf with %f/%c formats, a macro
 * that expands to a braced block of two printf statements, numeric
 * #if choosing the blend mode, and the ?: operator on colours.
 */
#include "aa_filters.h"
#include "macros_util.h"

#define CHECK_MODE 2     /* 0 plain, 1 filtered, 2 adaptive */

/* Debug prints are on unless the build says otherwise (-DNO_CHECKER_DEBUG). */
#ifndef NO_CHECKER_DEBUG
#define DEBUG_CHECKER
#endif

surface checker_modfloor(
    float Ka = 1, Kd = 1;
    float frequency = 8;
    color blackcolor = color(0.05), whitecolor = color(0.9);
    float debugcell = -1;)
{
    float ss = s * frequency, tt = t * frequency;

    float plain = mod(floor(ss) + floor(tt), 2);

    float fws = filterwidth(ss), fwt = filterwidth(tt);
    float filtered = filteredchecker(ss, tt, fws, fwt);

#if CHECK_MODE == 0
    float f = plain;
#elif CHECK_MODE == 1
    float f = filtered;
#else
    float f = mix(plain, filtered, smoothstep(0.05, 0.25, max(fws, fwt)));
#endif

    color Ct = (f > 0.999) ? whitecolor : ((f < 0.001) ? blackcolor : mix(blackcolor, whitecolor, f));

#ifdef DEBUG_CHECKER
    if (floor(ss) + 100 * floor(tt) == debugcell) {
        TRACEVAL("%f\n", f)
        TRACEVAL("%c\n", Ct)
    }
#endif

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
