/*
 * matrix_play.sl -- a projected grid pattern whose frame is built by
 * hand: the shader-space matrix is fetched, combined with a rotation,
 * a scale and a translation given as parameters, inverted by division,
 * and used to place the pattern; mirrored frames are detected through
 * the determinant.
 *
 * Exercises: matrix "shader" 1, matrix "world" 1, a matrix literal of
 * 16 values, matrix parameters, rotate()/scale()/translate() on
 * matrices, 1 / m and m1 / m2, determinant(), comp(m, row, col) and
 * setcomp(m, row, col, x), transform(matrix, P), transform("shader",
 * "world", P), vtransform(matrix, v) and ntransform(matrix, n) (which
 * uses the inverse transpose), printf with %m, and a function taking
 * and returning matrices.
 */

/* Remove any translation from a matrix (keep the 3x3 part). */
matrix linearpart(matrix m)
{
    matrix r = m;
    setcomp(r, 3, 0, 0);
    setcomp(r, 3, 1, 0);
    setcomp(r, 3, 2, 0);
    return r;
}

/* Largest axis scale of a matrix, from the lengths of its rows. */
float maxscale(matrix m)
{
    uniform float i;
    float best = 0;
    for (i = 0; i < 3; i += 1) {
        float l = sqrt(comp(m, i, 0) * comp(m, i, 0) + comp(m, i, 1) * comp(m, i, 1)
                       + comp(m, i, 2) * comp(m, i, 2));
        best = max(best, l);
    }
    return best;
}

surface matrix_play(
    float Ka = 1, Kd = 0.8;
    float angle = 30;
    vector rotaxis = vector(0, 0, 1);
    point gridscale = point(4, 4, 4);
    vector gridoffset = vector(0.1, 0.2, 0);
    matrix extra = 1;
    color linecolor = color(0.1, 0.1, 0.4), fillcolor = color(0.9, 0.85, 0.7);
    color mirrorcolor = color(0.9, 0.7, 0.7);
    float linewidth = 0.05;
    float verbose = 0;)
{
    matrix toshader = matrix "shader" 1;       /* shader -> current */
    matrix ident = (1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1);
    matrix frame = translate(scale(rotate(ident, radians(angle), rotaxis), gridscale), gridoffset);
    frame = frame * extra;

    /* current -> shader -> grid frame */
    matrix tograd = (1 / toshader) * (1 / frame);
    matrix viaworld = (matrix "world" 1) / (matrix "world" 1);   /* identity, the long way */
    tograd = tograd * viaworld;

    point Pg = transform(tograd, P);
    float mirrored = (determinant(linearpart(tograd)) < 0) ? 1 : 0;

    /* Grid lines in the frame's x and y. */
    float gx = xcomp(Pg) - floor(xcomp(Pg));
    float gy = ycomp(Pg) - floor(ycomp(Pg));
    float onx = 1 - smoothstep(linewidth * 0.5, linewidth, min(gx, 1 - gx));
    float ony = 1 - smoothstep(linewidth * 0.5, linewidth, min(gy, 1 - gy));
    float line = max(onx, ony);

    /* Shade lines by the grid's own normal direction (through the inverse transpose). */
    normal Ngrid = normalize(ntransform(tograd, normalize(N)));
    vector Vgrid = normalize(vtransform(tograd, -I));
    float facing = abs(Ngrid . Vgrid);

    point Pw = transform("shader", "world", transform("shader", P));
    float height = ycomp(Pw);

    if (verbose != 0) {
        printf("frame = %m\n", frame);
        printf("det = %f, maxscale = %f, height = %f\n", determinant(frame), maxscale(frame), height);
    }

    color base = (mirrored != 0) ? mirrorcolor : fillcolor;
    color Ct = mix(base, linecolor, line * (0.5 + 0.5 * facing));

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
