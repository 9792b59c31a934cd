/*
 * material.sl -- the VRML 97 Material node (ISO/IEC 14772-1, sec. 6.27 and
 * the lighting model of sec. 4.14), also fit for Wavefront OBJ/MTL
 * materials (Kd, Ks, Ns/128, 1 - d, Ke, map_Kd); this library's own.
 *
 * Ambient plus diffuse reflection of the diffuse colour, a Phong highlight
 * of the specular colour with exponent 128 * shininess, and an emissive
 * colour that glows without light.  The diffuse colour is diffusecolor
 * times Cs (white unless the object carries colours), times the diffuse
 * texture when one is named (as OBJ's map_Kd; a missing file leaves the
 * colour untextured).  The ambient light is scaled by ambientintensity, as
 * in VRML.  The opacity is 1 - transparency and the colour is
 * premultiplied by it.
 *
 * Parameters:
 *   diffusecolor     -- the diffuse (and ambient) colour (.8, .8, .8).
 *   specularcolor    -- the colour of the highlight (0, black: none).
 *   shininess        -- highlight sharpness, 0 to 1; the Phong exponent
 *                       is 128 * shininess (.2).
 *   transparency     -- 0 for opaque to 1 for invisible (0).
 *   emissivecolor    -- colour emitted regardless of lights (0, black).
 *   ambientintensity -- scale applied to the ambient light (.2).
 *   texturename      -- file name of the diffuse texture; "" means none ("").
 *   repeats, repeatt -- 1: the texture repeats along s (t); 0: the coordinate
 *                       is clamped to [0, 1], VRML's repeatS/repeatT FALSE (1).
 *   lit              -- 0: no lighting, the colour is the diffuse colour (VRML
 *                       draws a Shape without a Material so) (1).
 *   lightcategory    -- the lights that light it, as an illuminance
 *                       category ("-name": all but those of category name;
 *                       VRML 1.0's lights light only what follows them in
 *                       their Separator); "" means every light ("").
 */
surface material(color diffusecolor = .8; color specularcolor = 0;
                 float shininess = .2; float transparency = 0;
                 color emissivecolor = 0; float ambientintensity = .2;
                 string texturename = ""; float repeats = 1;
                 float repeatt = 1; float lit = 1;
                 string lightcategory = "";)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color Cd = diffusecolor * Cs;
    color Cspec = 0;
    float ss = s;
    float tt = t;

    if (repeats == 0)
        ss = clamp(s, 0, 1);
    if (repeatt == 0)
        tt = clamp(t, 0, 1);
    if (texturename != "")
        Cd *= color texture(texturename, ss, tt, "fill", 1);
    Oi = 1 - transparency;
    if (lit == 0) {
        Ci = Oi * Cd;
    } else if (lightcategory != "") {
        /* diffuse() and phong() over the category's lights only. */
        color Cdiff = 0;
        float lit_specular = comp(specularcolor, 0) + comp(specularcolor, 1) + comp(specularcolor, 2);
        float size = max(128 * shininess, 1);
        vector R = reflect(-V, Nf);
        illuminance(lightcategory, P, Nf, PI / 2) {
            vector Ln = normalize(L);
            Cdiff += Cl * (Ln . Nf);
            if (lit_specular > 0)
                Cspec += Cl * pow(max(0, R . Ln), size);
        }
        Ci = Oi * (emissivecolor
                   + Cd * (ambientintensity * ambient() + Cdiff)
                   + specularcolor * Cspec);
    } else {
        if (comp(specularcolor, 0) + comp(specularcolor, 1) + comp(specularcolor, 2) > 0)
            Cspec = specularcolor * phong(Nf, V, max(128 * shininess, 1));
        Ci = Oi * (emissivecolor
                   + Cd * (ambientintensity * ambient() + diffuse(Nf))
                   + Cspec);
    }
}
