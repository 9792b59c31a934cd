/*
 * wood.sl -- after the "wood" shaders of Upstill's "The RenderMan Companion"
 * (ch. 16) and the RISpec-era Pixar library: concentric growth rings.
 *
 * Solid texture evaluated in "shader" space, so the grain sticks to the
 * object.  The trunk runs along the shader-space z axis: the ring index is
 * the distance from that axis times ringscale.  The lookup point is first
 * swirled by a few octaves of vector noise (turbulence), and each ring
 * radius gets a little noise of its own, so rings wander and vary in width.
 * Within a ring the colour goes from lightwood (early wood) to darkwood
 * (late wood) with a sharp fall back at the ring boundary; grainy adds fine
 * streaks along the trunk.  Lit like "plastic".
 *
 * Parameters:
 *   Ka            -- scale applied to the ambient light (1).
 *   Kd            -- scale applied to the diffuse reflection (.75).
 *   Ks            -- scale applied to the specular highlight (.15).
 *   roughness     -- size of the specular highlight (.1).
 *   specularcolor -- colour of the highlight (1, white).
 *   ringscale     -- rings per shader-space unit of radius (10).
 *   txtscale      -- scales shader space before the lookup (1).
 *   swirl         -- strength of the turbulent distortion (.35).
 *   grainy        -- strength of the fine grain streaks, 0 to 1 (1).
 *   lightwood     -- colour of the early wood (.69, .44, .25).
 *   darkwood      -- colour of the late wood (.35, .22, .08).
 */
surface wood(float Ka = 1; float Kd = .75; float Ks = .15;
             float roughness = .1; color specularcolor = 1;
             float ringscale = 10; float txtscale = 1;
             float swirl = .35; float grainy = 1;
             color lightwood = color(.69, .44, .25);
             color darkwood = color(.35, .22, .08);)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    point PP = txtscale * transform("shader", P);
    vector offset = 0;
    float i, freq = 1, r, grain;
    color Ct;

    /* Three octaves of vector turbulence swirl the lookup point. */
    for (i = 0; i < 3; i += 1) {
        offset += (vector noise(PP * freq) - .5) / freq;
        freq *= 2;
    }
    PP += swirl * offset;

    /* Ring position: distance from the trunk axis, jittered per ring. */
    r = ringscale * sqrt(xcomp(PP) * xcomp(PP) + ycomp(PP) * ycomp(PP));
    r += .5 * float noise(r);
    r -= floor(r);
    r = smoothstep(0, .8, r) - smoothstep(.83, 1, r);

    /* Fine grain: thin streaks stretched along the trunk. */
    grain = float noise(point(xcomp(PP) * 60, ycomp(PP) * 60, zcomp(PP) * 4));
    r = clamp(r + grainy * .3 * smoothstep(.55, .75, grain), 0, 1);

    Ct = mix(lightwood, darkwood, r);

    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diffuse(Nf))
               + specularcolor * Ks * specular(Nf, V, roughness));
}
