/*
 * clouds_fbm.sl -- a cloud layer for a sky dome: fBm thresholded into
 * puffy clouds, with opacity following cloud density so the sky behind
 * shows through.
 *
 * Exercises: #define QUALITY before #include (config.h's #if/#elif picks
 * DEFAULT_OCTAVES from it through integer arithmetic), #ifdef / #else
 * around a feature switch, #undef of a local macro, fBm() and ridged()
 * from noises.h, filterwidthp(), transform() to a named space from a
 * string parameter, partial opacity, and color mix().
 */
#define QUALITY 2
#define CLOUD_RIDGES
#include "noises.h"

#ifdef CLOUD_RIDGES
#define CLOUD_DETAIL(p) (0.25 * ridged((p) * 4, 4, 2.1, .5, 1))
#else
#define CLOUD_DETAIL(p) 0
#endif

surface clouds_fbm(
    float Kd = .6, Ka = .6;
    float cloudfreq = .5, coverage = .45, softness = .2;
    float brightness = 1.2;
    color cloudcolor = color(1, 1, 1);
    color shadowcolor = color(.55, .58, .65);
    string cloudspace = "world";)
{
    point Pc = transform(cloudspace, P) * cloudfreq;
    float fw = filterwidthp(Pc);
    normal Nf = faceforward(normalize(N), I);

    /* Density: fBm plus optional ridged detail, octaves from QUALITY. */
    float dens = .5 + .5 * filteredfBm(Pc, fw, DEFAULT_OCTAVES, 2, .5);
    dens += CLOUD_DETAIL(Pc);
    dens = smoothstep(coverage - softness, coverage + softness, dens);

    /* Thick clouds are darker underneath. */
    float thick = smoothstep(.5, 1, dens);
    color Ccloud = mix(cloudcolor * brightness, shadowcolor, .6 * thick);

    Oi = dens * Os;
    Ci = Oi * Ccloud * (Ka * ambient() + Kd * diffuse(Nf) + .4);
}

#undef CLOUD_DETAIL
