/*
 * paintedplastic.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard surface shaders): "paintedplastic".
 *
 * The "plastic" shader with its base colour multiplied by a texture map
 * looked up at the standard texture coordinates (s, t).  The highlight is
 * not textured.  When no map is named the texture factor is white and the
 * shader behaves like "plastic".
 *
 * Parameters:
 *   Ks            -- scale applied to the specular highlight (.5).
 *   Kd            -- scale applied to the diffuse reflection (.5).
 *   Ka            -- scale applied to the ambient light (1).
 *   roughness     -- size of the specular highlight (.1).
 *   specularcolor -- colour of the highlight (1, white).
 *   texturename   -- name of the colour texture; "" means none ("").
 */
surface paintedplastic(float Ks = .5; float Kd = .5; float Ka = 1;
                       float roughness = .1; color specularcolor = 1;
                       string texturename = "";)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color Ct = Cs;

    if (texturename != "")
        Ct *= color texture(texturename);

    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diffuse(Nf))
               + specularcolor * Ks * specular(Nf, V, roughness));
}
