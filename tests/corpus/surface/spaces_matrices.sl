/*
 * spaces_matrices.sl -- a projection-paint shader: a stripe pattern is
 * projected from a user-built "paint" coordinate frame, made by composing
 * translate, rotate and scale with a space matrix.  Diagnostic colour
 * comes from properties of the matrices.
 *
 * Exercises: matrix "world" 1 and matrix "shader" 1 space casts, a
 * 16-float matrix literal, translate(), rotate(), scale(), matrix
 * multiplication and division (m1 / m2), comp() and setcomp() on
 * matrices, determinant(), transform(matrix, P), transform("from", "to",
 * P), vtransform() and ntransform() with named spaces, point "world",
 * vector "object" and normal "shader" space casts, the cross and dot
 * operators, and printf %m.
 */
#include "config.h"

surface spaces_matrices(
    float Ka = 1, Kd = .8;
    float angle = 30;
    vector axis = vector "world" (0, 1, 0);
    point origin = point "world" (0, 0, 0);
    float stretch = 2;
    float stripefreq = 10;
    float showdet = 0;)
{
    matrix toworld = matrix "world" 1;
    matrix shadermat = matrix "shader" 1;
    matrix ident = matrix (1, 0, 0, 0,
                           0, 1, 0, 0,
                           0, 0, 1, 0,
                           0, 0, 0, 1);

    /* Paint frame: rotate about "axis", stretch along x, move to origin. */
    matrix paint = ident;
    paint = translate(paint, vector(xcomp(origin), ycomp(origin), zcomp(origin)));
    paint = rotate(paint, radians(angle), axis);
    paint = scale(paint, point(stretch, 1, 1));

    /* A matrix can be adjusted element by element. */
    setcomp(paint, 3, 1, comp(paint, 3, 1) + .25);

    /* Compose the world matrix with the inverse of the paint frame. */
    matrix curtopaint = toworld / paint;
    point Ppaint = transform(curtopaint, P);

    float stripe = smoothstep(.4, .6, abs(mod(xcomp(Ppaint) * stripefreq, 2) - 1));

    /* Shader space and object space views of the same geometry. */
    point Pobj = transform("world", "object", transform("world", P));
    vector Xobj = vector "object" (1, 0, 0);
    normal Nsh = ntransform("shader", N);
    vector Vw = vtransform("world", Xobj);
    normal Nup = normal "shader" (0, 0, 1);
    float facing = abs(normalize(Nsh) . normalize(ntransform("shader", Nup)));
    vector side = normalize(Vw ^ vtransform("world", I));

    float det = determinant(shadermat * paint);
    color Cdiag = color(abs(xcomp(side)), facing, clamp(det / 10, 0, 1));
    if (showdet > 0 && abs(xcomp(Pobj)) < .01)
        printf("paint matrix %m, det %f\n", paint, det);

    color C = mix(Cs, color(1, 1, 1) - Cs, stripe);
    C = (showdet > 0) ? Cdiag : C;

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * C * (Ka * ambient() + Kd * diffuse(Nf));
}
