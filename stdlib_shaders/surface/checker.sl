/*
 * checker.sl -- a checkerboard in the texture coordinates (s, t); this
 * library's own, with the box-filtered pulse train of Apodaca & Gritz,
 * "Advanced RenderMan", sec. 11.4 ("filteredpulsetrain") for antialiasing.
 *
 * The board has `frequency` squares per unit of s and of t, alternating
 * between blackcolor and whitecolor (the square at s = t = 0 is black).
 * Each direction is a pulse train of duty 1/2 filtered over the width one
 * sample covers; the two are combined like an exclusive-or, which averages
 * correctly as the squares shrink to grey in the distance.
 *
 * The filter width is taken from the ray-differential globals du and dv,
 * which is exact for the default texture coordinates (s, t) = (u, v): the
 * RenderMan idiom filterwidth(s) = abs(Du(s)*du) + abs(Dv(s)*dv) needs
 * derivatives, which the JIT does not compile yet.  With zero du/dv the
 * board is the plain point-sampled step pattern.  Lit like "matte".
 *
 * Parameters:
 *   Ka         -- scale applied to the ambient light (1).
 *   Kd         -- scale applied to the diffuse reflection (1).
 *   frequency  -- squares per unit of s and of t (8).
 *   blackcolor -- colour of the square at the origin (0, black).
 *   whitecolor -- colour of the other squares (1, white).
 */

/* The integral from 0 to x of a pulse train of period 1 that is 0 below
 * edge and 1 from edge to 1 within each period. */
float checker_integral(float x, edge)
{
    return (1 - edge) * floor(x) + max(0, x - floor(x) - edge);
}

/* The pulse train of period 1 (0 below .5, 1 above within each period)
 * averaged over [x - w/2, x + w/2]; point-sampled for tiny widths. */
float checker_pulse(float x, w)
{
    float r;
    if (w < 1e-4)
        r = step(.5, x - floor(x));
    else
        r = (checker_integral(x + w / 2, .5) - checker_integral(x - w / 2, .5)) / w;
    return r;
}

surface checker(float Ka = 1; float Kd = 1; float frequency = 8;
                color blackcolor = 0; color whitecolor = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    float ss = frequency * s, tt = frequency * t;
    float sw = abs(frequency) * abs(du), tw = abs(frequency) * abs(dv);
    float a = checker_pulse(ss, sw), b = checker_pulse(tt, tw);
    float f = a * (1 - b) + b * (1 - a);
    color Ct = mix(blackcolor, whitecolor, f);

    Oi = Os;
    Ci = Os * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
