/*
 * palettes.h -- colour palettes and small array utilities.
 *
 * Exercises: include guards, functions taking array parameters of
 * unspecified length (float a[], color c[]), array indexing with
 * computed indices, loops over arrays, spline() over an array argument,
 * output array parameters, color "hsv" space casts.
 */
#ifndef PALETTES_H
#define PALETTES_H

/* Sum of the first n elements of an array. */
float ArraySum(float a[]; float n)
{
    float i, total = 0;
    for (i = 0; i < n; i += 1)
        total += a[i];
    return total;
}

/* Index of the first element of a sorted array that is greater than x. */
float ArrayFindInterval(float a[]; float n; float x)
{
    float i;
    for (i = 0; i < n; i += 1) {
        if (a[i] > x)
            break;
    }
    return i;
}

/* Piecewise-constant lookup: x in [0,1) picks one of n colours. */
color PaletteStep(color pal[]; float n; float x)
{
    float idx = clamp(floor(x * n), 0, n - 1);
    return pal[idx];
}

/* Smooth lookup through a colour array with a Catmull-Rom spline. */
color PaletteSmooth(color pal[]; float x)
{
    return color spline("catmull-rom", clamp(x, 0, 1), pal);
}

/* Fill an array with n colours of equally spaced hue. */
void RainbowFill(output color pal[]; float n; float sat, val)
{
    float i;
    for (i = 0; i < n; i += 1)
        pal[i] = color "hsv" (i / n, sat, val);
}

#endif /* PALETTES_H */
