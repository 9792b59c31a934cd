/*
 * functions_overload.sl -- "ceramic plate" whose pattern is assembled
 * from small user functions: two overloads of the same name chosen by
 * argument type, functions with output parameters, colour-returning
 * functions inside larger expressions, and functions nested inside the
 * shader body that reach shader parameters and locals through extern.
 *
 * Exercises: function overloading by parameter type (float vs point,
 * and colour vs float), void functions with several output parameters,
 * an output parameter that is also read, a function calling another
 * user function, nested functions declared in the shader body, extern
 * for a shader parameter, a shader local and the globals P/N/I,
 * a nested function assigning to an extern local, and returns from
 * inside if/else.
 */

/* Overload 1: bands along a single coordinate. */
float rings(float x; float freq)
{
    float f = mod(x * freq, 1);
    return smoothstep(0.4, 0.5, f) - smoothstep(0.9, 1, f);
}

/* Overload 2: concentric rings around the origin of a point. */
float rings(point p; float freq)
{
    float r = length(vector(xcomp(p), ycomp(p), 0));
    return rings(r, freq);
}

/* Overload by colour vs float: darken a colour, or a grey level. */
color glazed(color c; float k)
{
    return c * (1 - k) + k * c * c;
}
color glazed(float g; float k)
{
    if (k <= 0)
        return color(g);
    else
        return glazed(color(g, g, g), k);
}

/* Polar coordinates of p, and whether it lies inside radius rmax. */
void topolar(point p; float rmax; output float r, theta; output float inside)
{
    r = sqrt(xcomp(p) * xcomp(p) + ycomp(p) * ycomp(p));
    theta = atan(ycomp(p), xcomp(p));
    inside = (r <= rmax) ? 1 : 0;
}

/* Accumulate into an output parameter that is also read. */
void addscaled(output color acc; color c; float w)
{
    acc = acc + w * c;
}

surface functions_overload(
    float Ka = 1, Kd = 0.7, Ks = 0.5, roughness = 0.05;
    float platesize = 1, rimwidth = 0.1;
    float ringfreq = 6, petals = 8;
    color basecolor = color(0.95, 0.94, 0.9);
    color rimcolor = color(0.1, 0.2, 0.6);
    color petalcolor = color(0.6, 0.15, 0.2);
    float glaze = 0.3;)
{
    point Pp = transform("shader", P) / platesize;
    float specscale = 1;

    /* Nested: reads a shader parameter and a global, via extern. */
    color rimshade(float r)
    {
        extern float rimwidth;
        extern color rimcolor;
        return rimcolor * smoothstep(1 - rimwidth, 1 - rimwidth / 2, r);
    }

    /* Nested: changes an enclosing local through extern. */
    void dullen(float amount)
    {
        extern float specscale;
        specscale *= 1 - amount;
    }

    /* Nested: a complete local lighting model using globals. */
    color lit(color Ct)
    {
        extern normal N;
        extern vector I;
        extern float Ka, Kd, Ks, roughness, specscale;
        normal Nf = faceforward(normalize(N), I);
        return Ct * (Ka * ambient() + Kd * diffuse(Nf))
             + Ks * specscale * specular(Nf, -normalize(I), roughness);
    }

    float r, theta, inside;
    topolar(Pp, 1, r, theta, inside);

    /* Petals: an angular function of theta shaped by the point-overload rings. */
    float petal = smoothstep(0.3, 0.6, 0.5 + 0.5 * cos(theta * petals))
                * rings(Pp, ringfreq) * (1 - smoothstep(0.5, 0.7, r));

    color Ct = basecolor;
    addscaled(Ct, petalcolor - basecolor, petal);
    Ct += rimshade(r);
    Ct = glazed(Ct, glaze) * (0.9 + 0.1 * glazed(rings(r, 40), 0.5));

    if (inside == 0)
        dullen(0.8);                          /* unglazed underside */

    Oi = Os;
    Ci = Os * lit(Ct);
}
