/*
 * tiles_filterstep.sl -- square ceramic tiles with rounded grout lines,
 * every edge antialiased by the renderer's own filterstep(), a random
 * glaze colour per tile chosen from a colour array, and a slight
 * per-tile tilt of the shading normal.
 *
 * Exercises: filterstep(edge, x) with the "width" option and with the
 * three-argument interval form filterstep(edge, x0, x1), an array of
 * colours indexed by a computed float, cellnoise(point) returning a
 * vector, floor() tile ids, mod() with a negative-safe wrap, ntransform
 * and vtransform between "shader" and "current", faceforward, and
 * specular() on the tilted normal.
 */
surface tiles_filterstep(
    float Ka = 1, Kd = 0.8, Ks = 0.4, roughness = 0.08;
    float tilesize = 0.1, groutwidth = 0.006;
    float blurscale = 1;
    color groutcolor = color(0.45, 0.43, 0.4);
    color glazes[4] = {color(0.1, 0.3, 0.6), color(0.12, 0.35, 0.62),
                       color(0.9, 0.9, 0.85), color(0.08, 0.25, 0.5)};
    float tilt = 0.05;)
{
    point Pshad = transform("shader", P);
    float x = xcomp(Pshad) / tilesize;
    float y = ycomp(Pshad) / tilesize;
    float tx = floor(x), ty = floor(y);
    float fx = mod(x, 1), fy = mod(y, 1);      /* mod() keeps these in [0,1) even for x < 0 */
    uniform float gw = 0.5 * groutwidth / tilesize;

    /* Inside-the-tile mask: renderer-filtered steps on all four sides. */
    float inx = filterstep(gw, fx, "width", blurscale)
              - filterstep(1 - gw, fx, "width", blurscale);
    float iny = filterstep(gw, fy, "width", blurscale)
              - filterstep(1 - gw, fy, "width", blurscale);

    /* The interval form: filter explicitly over one sample's extent. */
    float dx = abs(Du(x) * du) + abs(Dv(x) * dv);
    float crack = filterstep(0.97, mod(x + y * 0.37, 1) - dx / 2,
                             mod(x + y * 0.37, 1) + dx / 2);
    float tile = clamp(inx * iny, 0, 1) * (1 - 0.3 * crack);

    /* Glaze chosen per tile. */
    float pick = floor(4 * float cellnoise(tx, ty));
    color glaze = glazes[clamp(pick, 0, 3)];

    /* Tilt each tile a little, built in shader space. */
    vector jitter = (vector cellnoise(point(tx, ty, 0)) - 0.5) * 2 * tilt;
    setzcomp(jitter, 0);
    vector jit = vtransform("shader", "current", jitter);
    normal Nt = normalize(N) + tile * normal jit;
    normal Nf = faceforward(normalize(Nt), I);
    normal Ngf = faceforward(normalize(N), I);

    color base = mix(groutcolor, glaze, tile);
    color spec = tile * Ks * specular(Nf, -normalize(I), roughness);

    Oi = Os;
    Ci = Os * (base * (Ka * ambient() + Kd * diffuse(Ngf)) + spec);
}
