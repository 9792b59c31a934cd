/* idioms_mix.sl: many small idioms in one shader: a filterwidth macro with an f-suffixed literal,
 * multi-name parameter groups, matrix/colour/point space casts as defaults, string and float arrays,
 * textureinfo into a uniform array, a texture channel index, a local named like a built-in (depth),
 * extern inside an illuminance block, output arguments, printf and compound assignment to P. */
#define PI 3.14159265
#define filterwidth(x) max(abs(Du(x)*du) + abs(Dv(x)*dv), 1e-6f)
float smoothpulse(float e0, e1, e2, e3, x) { return smoothstep(e0, e1, x) - smoothstep(e2, e3, x); }
void setup(output float a; float b) { a = b * 2; }
surface tricky(
    float Ka = 1, Kd = .5, Ks = .5, roughness = .1;
    color specularcolor = 1;
    string texname = "", envname = "";
    uniform matrix m = matrix "world" 1;
    float angle = radians(45), sides = 4;
    color tint = color "hsv" (.5, 1, 1);
    point center = point "shader" (0, 0, 0);
    output varying float mask = 0;
    float knots[4] = {0, .3, .6, 1};
    string names[2] = {"a", "b"};)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    float depth = depth(P);
    float fw = filterwidth(s);
    float x = 0, i;
    for (i = 0; i < sides; i += 1) {
        x += smoothpulse(.1, .2, .3, .4, mod(s * i, 1));
        if (x > 3) break;
    }
    uniform float res[2];
    textureinfo(texname, "resolution", res);
    color Ct = Cs;
    if (texname != "")
        Ct *= color texture(texname[0], s, t, "blur", fw);
    color Cr = 0;
    if (envname != "") {
        vector R = reflect(I, Nf);
        Cr = color environment(envname, vtransform("world", R));
    }
    float a;
    setup(a, x);
    mask = spline("catmull-rom", clamp(s, 0, 1), knots[0], knots[1], knots[2], knots[3]);
    float lum = comp(Ct, 0) * .3 + comp(Ct, 1) * .59 + comp(Ct, 2) * .11;
    color spec = 0;
    illuminance(P, Nf, PI/2) {
        extern normal Nf;
        vector Ln = normalize(L);
        spec += Cl * pow(max(0, Nf . normalize(Ln + V)), 1/roughness);
    }
    Oi = Os;
    Ci = Os * (Ct * tint * (Ka*ambient() + Kd*diffuse(Nf)) + specularcolor * Ks * spec + Cr) * lum * (1 - depth) * a;
    Ci = mix(Ci, color(1, 0, 0), float (names[0] == "a"));
    printf("%f %p %c\n", x, P, Ci);
    P += 0 * Nf;
}
