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
 */
surface material(color diffusecolor = .8; color specularcolor = 0;
                 float shininess = .2; float transparency = 0;
                 color emissivecolor = 0; float ambientintensity = .2;
                 string texturename = "";)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color Cd = diffusecolor * Cs;
    color Cspec = 0;

    if (texturename != "")
        Cd *= color texture(texturename, s, t, "fill", 1);
    if (comp(specularcolor, 0) + comp(specularcolor, 1) + comp(specularcolor, 2) > 0)
        Cspec = specularcolor * phong(Nf, V, max(128 * shininess, 1));

    Oi = 1 - transparency;
    Ci = Oi * (emissivecolor
               + Cd * (ambientintensity * ambient() + diffuse(Nf))
               + Cspec);
}
