/*
 * decal_projector.sl -- projects a decal (a texture with alpha, or a
 * procedural badge) onto an object through a placement frame: a matrix
 * parameter, adjusted by an offset, a spin and a size.  Mirrored frames
 * are detected from the sign of the determinant.
 *
 * Exercises: a matrix shader parameter, a 16-float matrix literal,
 * translate(), rotate() and scale() of a matrix, matrix division for the
 * inverse (ident / frame), determinant(), comp() and setcomp() on matrix
 * elements, transform(matrix, point), transform("world", "object", P),
 * vector "object" and point casts, pnoise() with a point period for a
 * wobbly badge edge, texture() with an alpha channel index, and the
 * && operator in a ?: condition.
 */
surface decal_projector(
    float Ka = 1, Kd = .8, Ks = .3, roughness = .1;
    matrix placement = 1;
    vector offset = vector "object" (0, 0, 0);
    float spin = 0, size = 1;
    string decalname = "";
    float wobblefreq = 6;
    color decalcolor = color(.9, .1, .1);)
{
    matrix ident = matrix (1, 0, 0, 0,
                           0, 1, 0, 0,
                           0, 0, 1, 0,
                           0, 0, 0, 1);

    /* Build the decal frame (in object space) and flatten its depth offset. */
    matrix frame = placement;
    frame = translate(frame, offset);
    frame = rotate(frame, radians(spin), vector(0, 0, 1));
    frame = scale(frame, point(size, size, size));
    matrix flat = frame;
    setcomp(flat, 3, 2, 0);
    point origin = point(comp(frame, 3, 0), comp(frame, 3, 1), comp(frame, 3, 2));

    /* Object-space position, then decal coordinates through the inverse frame. */
    point Pw = transform("world", P);
    point Pobj = transform("world", "object", Pw);
    point Pd = transform(ident / flat, Pobj);
    float ds = xcomp(Pd) + .5, dt = ycomp(Pd) + .5;
    if (determinant(frame) < 0)
        ds = 1 - ds;

    float inside = (ds >= 0 && ds <= 1 && dt >= 0 && dt <= 1) ? 1 : 0;
    float fade = 1 - smoothstep(size, 2 * size, distance(Pobj, origin));

    color Cdec = decalcolor;
    float adec = 0;
    if (decalname != "") {
        Cdec = color texture(decalname, ds, dt);
        adec = float texture(decalname[3], ds, dt);
    } else {
        point pd = point(ds, dt, 0);
        float r = distance(pd, point(.5, .5, 0));
        float wob = .03 * pnoise(pd * wobblefreq, point(wobblefreq, wobblefreq, 1));
        adec = 1 - smoothstep(.4 + wob, .42 + wob, r);
    }
    adec *= inside * fade;

    /* Decals are glossier along the object's x axis (a brushed sticker). */
    vector objx = normalize(vector "object" (1, 0, 0));
    float streak = abs(objx . normalize(dPdu));

    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color C = mix(Cs, Cdec, adec);
    Oi = Os;
    Ci = Os * (C * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * (1 + adec * streak) * specular(Nf, V, roughness));
}
