/*
 * marble.sl -- after the "marble" shader of Upstill's "The RenderMan
 * Companion" (ch. 16) and Perlin's marble (SIGGRAPH 1985): veined stone
 * from turbulence and a colour spline.
 *
 * A solid texture in "shader" space.  Fractal turbulence (the sum of
 * |noise - .5| over octaves of doubling frequency, each weighted by its
 * inverse frequency) distorts a set of parallel bands across shader-space
 * x; |sin| of the distorted position, raised to a power, peaks in thin
 * winding veins.  That value is mapped through a Catmull-Rom colour spline
 * running from the pale base colour into the dark veins.  Lit like
 * "plastic", with a fairly tight highlight for a polished look.
 *
 * Parameters:
 *   Ka            -- scale applied to the ambient light (1).
 *   Kd            -- scale applied to the diffuse reflection (.6).
 *   Ks            -- scale applied to the specular highlight (.4).
 *   roughness     -- size of the specular highlight (.05).
 *   specularcolor -- colour of the highlight (1, white).
 *   veinfreq      -- veins per unit of shader-space x (1.5).
 *   octaves       -- number of turbulence octaves (5).
 *   distortion    -- how far the turbulence bends the veins (2).
 *   sharpness     -- exponent narrowing the veins; larger is thinner (8).
 *   basecolor     -- colour of the stone between the veins (.9, .88, .85).
 *   veincolor     -- colour of the veins (.25, .25, .35).
 */
surface marble(float Ka = 1; float Kd = .6; float Ks = .4;
               float roughness = .05; color specularcolor = 1;
               float veinfreq = 1.5; float octaves = 5; float distortion = 2;
               float sharpness = 8;
               color basecolor = color(.9, .88, .85);
               color veincolor = color(.25, .25, .35);)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    point PP = veinfreq * transform("shader", P);
    float i, freq = 2, turb = 0, csp;
    color Ct;

    for (i = 0; i < octaves; i += 1) {
        turb += abs(float noise(PP * freq) - .5) / freq;
        freq *= 2;
    }

    csp = pow(abs(sin(PI * (xcomp(PP) + distortion * turb))), sharpness);
    Ct = spline(csp,
                basecolor, basecolor,
                mix(basecolor, veincolor, .1),
                mix(basecolor, veincolor, .4),
                veincolor,
                mix(veincolor, color 0, .4),
                mix(veincolor, color 0, .4));

    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diffuse(Nf))
               + specularcolor * Ks * specular(Nf, V, roughness));
}
