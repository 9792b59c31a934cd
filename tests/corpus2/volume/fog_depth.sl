/*
 * fog_depth.sl -- atmosphere with two kinds of haze: a depth-cue haze
 * from the renderer's normalised depth() between near and far planes,
 * and an exponential fog over the true ray length, optionally thinner
 * with height in world space.  Lit fog is approximated by averaging the
 * lights that declare __foglight.
 *
 * Exercises: a volume shader reading and rewriting Ci and Oi, depth(P),
 * length(I) as the ray length, transform("world", P) and E (the ray
 * origin) in world space, exp() with a height-integrated density,
 * illuminance(P) with no axis inside a volume shader and
 * lightsource("__foglight", f) filtering lights, mix() of colours by a
 * float, and a string parameter selecting the mode.
 */
volume fog_depth(
    string mode = "exp";                 /* "depthcue", "exp" or "both" */
    color fogcolor = color(0.6, 0.65, 0.7);
    float mindistance = 0, maxdistance = 1;   /* in depth() units */
    float density = 0.05;
    float heightfalloff = 0;             /* 0: uniform fog */
    float baseheight = 0;
    float Klit = 0;)
{
    float ray = length(I);

    /* Depth cue: 0 at mindistance, 1 at maxdistance. */
    float d = depth(P);
    float cue = clamp((d - mindistance) / max(maxdistance - mindistance, 1.0e-6), 0, 1);

    /* Exponential fog; integrate exp(-k (y - base)) analytically along the ray. */
    float tau = density * ray;
    if (heightfalloff > 0) {
        point Pw = transform("world", P);
        point Ew = transform("world", E);
        float y0 = ycomp(Ew) - baseheight, y1 = ycomp(Pw) - baseheight;
        float dy = y1 - y0;
        float k = heightfalloff;
        float integral = (abs(dy) > 1.0e-4)
                       ? (exp(-k * y0) - exp(-k * y1)) / (k * dy)
                       : exp(-k * y0);
        tau = density * ray * integral;
    }
    float fogexp = 1 - exp(-tau);

    float amount;
    if (mode == "depthcue")
        amount = cue;
    else if (mode == "both")
        amount = max(cue, fogexp);
    else
        amount = fogexp;

    /* Optional lit fog: average the fog-casting lights reaching P. */
    color fc = fogcolor;
    if (Klit > 0) {
        color lit = 0;
        float n = 0;
        illuminance(P) {
            float fl = 1;
            lightsource("__foglight", fl);
            if (fl > 0) {
                lit += Cl;
                n += 1;
            }
        }
        if (n > 0)
            fc = mix(fogcolor, fogcolor * lit / n, Klit);
    }

    Ci = mix(Ci, fc, amount);
    Oi = mix(Oi, color 1, amount);
}
