/*
 * noises.h -- rtsl's standard header: signed noise, fractal sums and
 * cellular noise, band-limited by a filter width, under the names shader
 * collections expect (Apodaca and Gritz, "Advanced RenderMan", chapter
 * 10).  The definitions are this library's own.
 *
 *   snoise(x), vsnoise(x)        noise and vector noise in [-1, 1].
 *   filteredsnoise(p, width), filteredvsnoise(p, width)
 *                                fade to 0 (the average) as the filter
 *                                width reaches the noise's frequency.
 *   fBm(p, filtwidth, octaves, lacunarity, gain)
 *                                fractional Brownian motion: octaves of
 *                                filtered signed noise, each lacunarity
 *                                times finer and gain times weaker,
 *                                each fading out as it would alias.
 *   vfBm(...)                    the same of vector noise.
 *   turbulence(p, filtwidth, octaves, lacunarity, gain)
 *                                the same of |snoise|.
 *   voronoi_f1_3d(p, jitter, f1, pos1)
 *                                the distance f1 to the nearest of
 *                                jittered cell points, and that point.
 */
#ifndef NOISES_H
#define NOISES_H 1

#include "filterwidth.h"

#define snoise(x) (2 * (float noise(x)) - 1)
#define vsnoise(x) (2 * (vector noise(x)) - 1)
#define filteredsnoise(p, width) (snoise(p) * (1 - smoothstep(0.2, 0.75, width)))
#define filteredvsnoise(p, width) (vsnoise(p) * (1 - smoothstep(0.2, 0.75, width)))

float fBm(point p; float filtwidth; uniform float octaves, lacunarity, gain)
{
    uniform float amp = 1;
    varying point pp = p;
    varying float sum = 0, fw = filtwidth;
    uniform float i;
    for (i = 0; i < octaves; i += 1) {
        sum += amp * filteredsnoise(pp, fw);
        amp *= gain;
        pp *= lacunarity;
        fw *= lacunarity;
    }
    return sum;
}

vector vfBm(point p; float filtwidth; uniform float octaves, lacunarity, gain)
{
    uniform float amp = 1;
    varying point pp = p;
    varying vector sum = 0;
    varying float fw = filtwidth;
    uniform float i;
    for (i = 0; i < octaves; i += 1) {
        sum += amp * filteredvsnoise(pp, fw);
        amp *= gain;
        pp *= lacunarity;
        fw *= lacunarity;
    }
    return sum;
}

float turbulence(point p; float filtwidth; uniform float octaves, lacunarity, gain)
{
    uniform float amp = 1;
    varying point pp = p;
    varying float sum = 0, fw = filtwidth;
    uniform float i;
    for (i = 0; i < octaves; i += 1) {
        float n = filteredsnoise(pp, fw);
        /* |n| averaged over a filter wider than a cell is about 1/2 of the range */
        sum += amp * mix(abs(n), 0.3, smoothstep(0.2, 0.75, fw));
        amp *= gain;
        pp *= lacunarity;
        fw *= lacunarity;
    }
    return sum;
}

void voronoi_f1_3d(point p; float jitter; output float f1; output point pos1)
{
    point cell = point(floor(xcomp(p)) + 0.5, floor(ycomp(p)) + 0.5, floor(zcomp(p)) + 0.5);
    f1 = 1000;
    pos1 = cell;
    float i, j, k;
    for (i = -1; i <= 1; i += 1) {
        for (j = -1; j <= 1; j += 1) {
            for (k = -1; k <= 1; k += 1) {
                point testcell = cell + vector(i, j, k);
                point pos = testcell + jitter * (vector cellnoise(testcell) - 0.5);
                float d = distance(pos, p);
                if (d < f1) {
                    f1 = d;
                    pos1 = pos;
                }
            }
        }
    }
}

#endif
