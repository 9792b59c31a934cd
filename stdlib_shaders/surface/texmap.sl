/*
 * texmap.sl -- a texture-mapped surface with a fallback colour; this
 * library's own, in the style of RISpec Appendix A's "paintedplastic".
 *
 * The colour comes from a texture map looked up at (s, t), transformed by
 * scale and offset (s' = s * sscale + soffset, likewise t) so a map can be
 * tiled or shifted.  When no map is named, or the named file cannot be
 * read, the surface shows fallbackcolor (by default a loud magenta, so a
 * missing map is noticed) -- the lookup asks for a fill of -1, which no
 * real image gives, to tell a missing map from a present one.  The colour
 * is multiplied by Cs and lit like "plastic".
 *
 * Parameters:
 *   Ka            -- scale applied to the ambient light (1).
 *   Kd            -- scale applied to the diffuse reflection (.8).
 *   Ks            -- scale applied to the specular highlight (.2).
 *   roughness     -- size of the specular highlight (.1).
 *   specularcolor -- colour of the highlight (1, white).
 *   texturename   -- file name of the colour texture; "" means none ("").
 *   fallbackcolor -- colour shown when the map is missing (1, 0, 1).
 *   sscale        -- scale applied to s before the lookup (1).
 *   tscale        -- scale applied to t before the lookup (1).
 *   soffset       -- offset added to s after scaling (0).
 *   toffset       -- offset added to t after scaling (0).
 */
surface texmap(float Ka = 1; float Kd = .8; float Ks = .2;
               float roughness = .1; color specularcolor = 1;
               string texturename = "";
               color fallbackcolor = color(1, 0, 1);
               float sscale = 1; float tscale = 1;
               float soffset = 0; float toffset = 0;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color Ct = fallbackcolor;
    color Cm;

    if (texturename != "") {
        Cm = color texture(texturename, s * sscale + soffset,
                           t * tscale + toffset, "fill", -1);
        if (comp(Cm, 0) >= 0)
            Ct = Cm;
    }
    Ct *= Cs;

    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diffuse(Nf))
               + specularcolor * Ks * specular(Nf, V, roughness));
}
