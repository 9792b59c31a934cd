/*
 * interior_absorb.sl -- an interior volume for glass or water objects:
 * light passing through the inside is absorbed exponentially with path
 * length (Beer's law), with a wavelength-dependent absorption colour.
 * Surfaces read its "density" and "murk" parameters with opposite() and
 * incident().
 *
 * Exercises: a volume shader used as an interior, length(I), exp() per
 * colour channel through color() construction with comp(), output
 * uniform parameters that other shaders query, and mix() on Oi.
 */
volume interior_absorb(
    float density = 1;
    color absorbcolor = color(.4, .1, .05);
    output uniform float murk = .3;
    output uniform float scatter = .1;
    color scattercolor = color(.1, .3, .35);)
{
    float pathlen = length(I) * density;
    color trans = color(exp(-comp(absorbcolor, 0) * pathlen),
                        exp(-comp(absorbcolor, 1) * pathlen),
                        exp(-comp(absorbcolor, 2) * pathlen));
    float inscatter = (1 - exp(-scatter * pathlen)) * murk;

    Ci = Ci * trans + inscatter * scattercolor;
    Oi = mix(Oi, color(1, 1, 1), inscatter);
}
