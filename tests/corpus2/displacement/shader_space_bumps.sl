/*
 * shader_space_bumps.sl -- round bumps laid out on a jittered grid in
 * shader space, with the displacement amount expressed in the units of a
 * chosen coordinate system so the bumps keep their size whatever the
 * object's scale.  True displacement or bump only, by a switch.
 *
 * Exercises: a helper function that modifies the globals P and N
 * through extern declarations, vtransform(string, v) to measure the
 * size of a unit in a named space, P += ...; N = calculatenormal(P);
 * bump-only N = normalize(calculatenormal(P + offset)), transform
 * ("shader", P), cellnoise() jitter per cell returning a point,
 * floor()-based cell search over the 3x3 neighbourhood with nested
 * uniform loops, distance(), and a return value from the helper.
 */

/* Displace along dir by amp units of "space"; returns the space's scale. */
float displace_in(vector dir; string space; float amp, truedisp)
{
    extern point P;
    extern normal N;
    float spacescale = length(vtransform(space, dir));
    vector offset = dir * (amp / max(spacescale, 1.0e-6));
    if (truedisp != 0) {
        P += offset;
        N = calculatenormal(P);
    } else {
        N = normalize(calculatenormal(P + offset));
    }
    return spacescale;
}

displacement shader_space_bumps(
    float Km = 0.05;
    float frequency = 6;
    float bumpradius = 0.35, jitter = 0.6;
    string dispspace = "shader";
    float truedisp = 1;
    float dimples = 0;)
{
    point Pp = transform("shader", P) * frequency;
    point cell = point(floor(xcomp(Pp)), floor(ycomp(Pp)), floor(zcomp(Pp)));

    /* Nearest jittered feature point among the 27 neighbouring cells. */
    float nearest = 1.0e6;
    uniform float i, j, k;
    for (i = -1; i <= 1; i += 1) {
        for (j = -1; j <= 1; j += 1) {
            for (k = -1; k <= 1; k += 1) {
                point c = cell + vector(i, j, k);
                point feature = c + 0.5 + jitter * (point cellnoise(c) - 0.5);
                nearest = min(nearest, distance(Pp, feature));
            }
        }
    }

    /* A smooth round cap of radius bumpradius. */
    float x = clamp(nearest / bumpradius, 0, 1);
    float hump = sqrt(max(0, 1 - x * x));
    if (dimples != 0)
        hump = -hump;

    normal Nn = normalize(N);
    float scale = displace_in(vector Nn, dispspace, Km * hump, truedisp);
    if (scale <= 0)
        printf("shader_space_bumps: degenerate space \"%s\"\n", dispspace);
}
