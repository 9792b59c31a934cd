/*
 * smoke_marched.sl -- ray-marched, self-lit smoke: density is periodic
 * turbulent noise in "shader" space, sampled at jittered steps along the
 * ray, lit by every light at each step, and composited front to back
 * with trapezoid-rule optical depth, stopping early once the smoke is
 * opaque.
 *
 * Exercises: a volume shader marching from E to P (P - I is the ray
 * origin), transform("shader", ...) of every sample, pnoise(point,
 * point) for tileable density, a user density function with output
 * parameters, random() jitter, a while loop with a varying condition
 * and a break, illuminance(point) inside the loop, Oi/Ci accumulation
 * (premultiplied, front to back), exp() of a colour, and uniform
 * parameters for the step size and period.
 */
#define MAXSTEPS 200

/* Density of the smoke at a shader-space point; also returns its gradient length hint. */
float smokedensity(point Pd; float freq, period; uniform float octaves; output float detail)
{
    float sum = 0, amp = 1;
    point pp = Pd * freq;
    point per = point(period, period, period);
    uniform float i;
    detail = 0;
    for (i = 0; i < octaves; i += 1) {
        float n = abs(2 * float pnoise(pp, per) - 1);
        sum += amp * n;
        detail += amp * n * n;
        amp *= 0.5;
        pp *= 2;
        per *= 2;
    }
    return sum;
}

volume smoke_marched(
    float density = 1;
    float freq = 2, period = 8;
    uniform float octaves = 4;
    float stepsize = 0.1;
    float jitter = 1;
    float maxdist = 50;
    color smokecolor = color(0.6);
    color lightscale = 1;
    float thresh = 0.3, softness = 0.2;)
{
    point origin = P - I;                   /* = E for an atmosphere */
    float raylen = min(length(I), maxdist);
    vector dir = normalize(I);

    color Cv = 0, Ov = 0;
    float dist = stepsize * jitter * float random();
    float last_dtau = 0;
    color last_li = 0;
    float nsteps = 0;

    while (dist <= raylen && nsteps < MAXSTEPS) {
        point Pcur = origin + dist * dir;
        float det;
        float dens = smokedensity(transform("shader", Pcur), freq, period, octaves, det);
        dens = density * smoothstep(thresh - softness, thresh + softness, dens);
        float dtau = dens * stepsize;

        color li = 0;
        if (dens > 0) {
            illuminance(Pcur) {
                li += Cl;
            }
        }
        li *= lightscale * smokecolor * (0.8 + 0.2 * det);

        /* Trapezoid rule over the step. */
        float tau = 0.5 * (dtau + last_dtau);
        color lightstep = 0.5 * (li * dtau + last_li * last_dtau);
        Cv += (1 - Ov) * lightstep;
        Ov += (1 - Ov) * (1 - exp(-tau));

        if (comp(Ov, 0) > 0.995 && comp(Ov, 1) > 0.995 && comp(Ov, 2) > 0.995)
            break;

        last_dtau = dtau;
        last_li = li;
        dist += stepsize;
        nsteps += 1;
    }

    /* Composite the smoke over what was behind it. */
    Ci = Cv + (1 - Ov) * Ci;
    Oi = Ov + (1 - Ov) * Oi;
}
