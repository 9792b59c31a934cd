/*
 * patterns.h -- periodic and step-like pattern primitives, with box-filtered
 * versions for antialiasing.
 *
 * Exercises: #include of another header (filterwidth.h), include guards,
 * function-like macros with several arguments, macros expanding to macros,
 * statement macros with line continuations, #undef, a header function
 * that contains a nested function reaching its enclosing locals via
 * extern, and plain functions with several parameter groups.
 */
#ifndef PATTERNS_H
#define PATTERNS_H

#include "filterwidth.h"

/* 1 between a and b, 0 elsewhere. */
#define pulse(a, b, x) (step((a), (x)) - step((b), (x)))

/* A linear ramp from 0 at a to 1 at b. */
#define boxstep(a, b, x) clamp(((x) - (a)) / ((b) - (a)), 0, 1)

/* Where x falls inside its tile, and which tile it is in. */
#define repeat(x, freq) mod((x) * (freq), 1.0)
#define whichtile(x, freq) floor((x) * (freq))

/* A pulse whose width is given as a fraction of the period (macro of macros). */
#define pulsetrain(duty, period, x) pulse(0, (duty), repeat((x), 1 / (period)))

/* Rotate (x, y) about (ox, oy) by rad radians, writing rx and ry. */
#define rotate2d(x, y, rad, ox, oy, rx, ry) \
    rx = ((x) - (ox)) * cos(rad) - ((y) - (oy)) * sin(rad) + (ox); \
    ry = ((x) - (ox)) * sin(rad) + ((y) - (oy)) * cos(rad) + (oy)

/* Helper used only by the functions below. */
#define PT_HALF(w) (0.5 * (w))

/*
 * Box-filtered pulse: the average of pulse(edge0, edge1, x) over an
 * interval of width fw centred on x.
 */
float filteredpulse(float edge0, edge1, x, fw)
{
    float x0 = x - PT_HALF(fw);
    float x1 = x0 + fw;
    return max(0, (min(x1, edge1) - max(x0, edge0)) / fw);
}

/*
 * Box-filtered pulse train: within each period the signal is 1 for the
 * first "duty" units and 0 for the rest.  We integrate the train
 * analytically over the filter interval and divide by its width.
 */
float filteredpulsetrain(float duty, period, x, fw)
{
    float w = max(fw / period, MINFILTWIDTH);
    float lo = x / period - PT_HALF(w);
    float hi = lo + w;
    float d = duty / period;

    /* Integral of the unit-period train from 0 to t. */
    float cumulative(float x)
    {
        extern float d;
        return floor(x) * d + min(x - floor(x), d);
    }

    return (cumulative(hi) - cumulative(lo)) / w;
}

/* Box-filtered step: filterstep with an explicit width, as a function. */
float filteredstep(float edge, x, fw)
{
    return clamp((x + PT_HALF(fw) - edge) / fw, 0, 1);
}

#undef PT_HALF

#endif /* PATTERNS_H */
