/*
 * plastic.sl -- RenderMan Interface Specification 3.2, Appendix A (standard
 * surface shaders): "plastic".
 *
 * The classic plastic model: a diffuse base coloured by Cs plus a specular
 * highlight whose colour is independent of the base (specularcolor, white by
 * default), as for a dielectric coating.
 *
 * Parameters:
 *   Ks            -- scale applied to the specular highlight (.5).
 *   Kd            -- scale applied to the diffuse reflection (.5).
 *   Ka            -- scale applied to the ambient light (1).
 *   roughness     -- size of the specular highlight (.1).
 *   specularcolor -- colour of the highlight (1, white).
 */
surface plastic(float Ks = .5; float Kd = .5; float Ka = 1;
                float roughness = .1; color specularcolor = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);

    Oi = Os;
    Ci = Os * (Cs * (Ka * ambient() + Kd * diffuse(Nf))
               + specularcolor * Ks * specular(Nf, V, roughness));
}
