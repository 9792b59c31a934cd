/*
 * patterns.h -- rtsl's standard header: pulses, steps and their
 * antialiased (box-filtered) forms, under the names shader collections
 * expect (Apodaca and Gritz, "Advanced RenderMan", chapter 11).  The
 * definitions are this library's own.  A filtered function takes the
 * filter width of its argument (see filterwidth.h) and returns the
 * average of the unfiltered one over [x - dx/2, x + dx/2].
 *
 *   pulse(a, b, x)                     1 where a <= x < b, else 0.
 *   filteredpulse(a, b, x, dx)         pulse, box-filtered.
 *   pulsetrain(edge, period, x)        1 over [0, edge) of every period.
 *   filteredpulsetrain(edge, period, x, dx)
 *   smoothpulse(e0, e1, e2, e3, x)     up by smoothstep(e0, e1), down by
 *                                      smoothstep(e2, e3).
 *   smoothpulsetrain(e0, e1, e2, e3, period, x)
 *   filteredsmoothstep(e0, e1, x, dx)  smoothstep, widened by the filter.
 *   filteredabs(x, dx)                 abs, box-filtered.
 *   filteredstep(edge, x, dx)          step, box-filtered.
 */
#ifndef PATTERNS_H
#define PATTERNS_H 1

#include "filterwidth.h"

#define pulse(a, b, x) (step((a), (x)) - step((b), (x)))

float filteredpulse(float edge0, edge1, x, dx)
{
    float x0 = x - dx / 2;
    float x1 = x0 + dx;
    return max(0, (min(x1, edge1) - max(x0, edge0)) / dx);
}

float pulsetrain(float edge, period, x)
{
    return pulse(0, edge, mod(x, period));
}

/* The integral of pulsetrain from 0 to x, for filtering it. */
float pulsetrain_integral_(float edge, period, x)
{
    float cycles = floor(x / period);
    return cycles * edge + min(edge, x - cycles * period);
}

float filteredpulsetrain(float edge, period, x, dx)
{
    float w = max(dx, 1.0e-6);
    float x0 = x - w / 2;
    return (pulsetrain_integral_(edge, period, x0 + w)
            - pulsetrain_integral_(edge, period, x0)) / w;
}

float smoothpulse(float e0, e1, e2, e3, x)
{
    return smoothstep(e0, e1, x) - smoothstep(e2, e3, x);
}

float smoothpulsetrain(float e0, e1, e2, e3, period, x)
{
    return smoothpulse(e0, e1, e2, e3, mod(x, period));
}

float filteredsmoothstep(float edge0, edge1, x, dx)
{
    return smoothstep(edge0 - dx / 2, edge1 + dx / 2, x);
}

/* The integral of abs from 0 to x. */
float abs_integral_(float x)
{
    return x * abs(x) / 2;
}

float filteredabs(float x, dx)
{
    float w = max(dx, 1.0e-6);
    return (abs_integral_(x + w / 2) - abs_integral_(x - w / 2)) / w;
}

float filteredstep(float edge, x, dx)
{
    float w = max(dx, 1.0e-6);
    return clamp((x + w / 2 - edge) / w, 0, 1);
}

#endif
