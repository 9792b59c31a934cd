/*
 * texture_channels.sl -- a decal shader that reads a colour map, its alpha
 * from a chosen channel, a separate single-channel roughness map, and a
 * sharp, unfiltered mask, and lays the decal over the base plastic.
 *
 * Exercises: texture() with a channel index on a string variable
 * (mapname[3]) and on a string literal ("rough.tx"[1]), optional
 * parameter lists ("blur", "width", "swidth", "twidth", "filter"), the
 * four-corner texture form, textureinfo() with "resolution" and
 * "channels", Du()/Dv() of s and t for manual filter widths, uniform
 * float array locals, string tests, and ?:.
 */
surface texture_channels(
    float Ka = 1, Kd = .8, Ks = .4, roughness = .1;
    string mapname = "";
    string maskname = "";
    float blur = 0;
    float decalchannel = 3;)
{
    color Cd = Cs;
    float decalalpha = 0;
    float rough = roughness;
    uniform float res[2] = {1, 1};
    uniform float nchan = 0;

    if (mapname != "") {
        textureinfo(mapname, "resolution", res);
        textureinfo(mapname, "channels", nchan);

        /* Filter widths, in texels, from the screen-space derivatives. */
        float sw = abs(Du(s) * du) + abs(Dv(s) * dv);
        float tw = abs(Du(t) * du) + abs(Dv(t) * dv);

        Cd = color texture(mapname, s, t, "blur", blur, "swidth", 1, "twidth", 1);
        decalalpha = (nchan > 3) ? float texture(mapname[decalchannel], s, t, "blur", blur)
                            : 1;
        decalalpha *= (max(sw * res[0], tw * res[1]) < 64) ? 1 : .5;

        /* Roughness from the second channel of a fixed map. */
        rough = roughness * (.5 + float texture("rough.tx"[1], s, t, "filter", "gaussian"));
    }

    /* A hard-edged stencil: no filtering at all (width 0). */
    float stencil = 1;
    if (maskname != "") {
        stencil = float texture(maskname, s, t, "width", 0);
        stencil *= float texture(maskname, s, t, s + du, t, s, t + dv, s + du, t + dv);
    }

    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color Cbase = mix(Cs, Cd, decalalpha * stencil);

    Oi = Os;
    Ci = Os * (Cbase * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * specular(Nf, V, rough));
}
