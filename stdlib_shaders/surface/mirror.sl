/*
 * mirror.sl -- a ray-traced mirror; this library's own, in the style of
 * the BMRT "mirror" shader and Apodaca & Gritz, "Advanced RenderMan"
 * (ch. 11, ray-traced reflections).
 *
 * Reflects the scene with trace() along the mirror direction, scaled by Kr
 * and tinted by specularcolor, and adds "plastic"-like highlights from the
 * light sources and an optional diffuse base (off by default).  The
 * renderer bounds the recursion: beyond its ray depth trace() is black.
 * Where the application lowers the ray parameter "relevance" below 1
 * (docs/ray_parameters.md), reflections are traced only while raydepth()
 * is below 4 * relevance: none at relevance 0.
 *
 * Parameters:
 *   Ka            -- scale applied to the ambient light (0).
 *   Kd            -- scale applied to the diffuse reflection (0).
 *   Ks            -- scale applied to the specular highlight (1).
 *   Kr            -- scale applied to the traced reflection (1).
 *   roughness     -- size of the specular highlight (.05).
 *   specularcolor -- colour of the highlight and the reflection (1, white).
 */
surface mirror(float Ka = 0; float Kd = 0; float Ks = 1; float Kr = 1;
               float roughness = .05; color specularcolor = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    vector R = reflect(normalize(I), Nf);
    color Crefl = 0;
    float relevance = 1;

    rayinfo("relevance", relevance);
    if (Kr > 0 && (relevance >= 1 || raydepth() < 4 * relevance))
        Crefl = Kr * color trace(P, R);

    Oi = Os;
    Ci = Os * (Cs * (Ka * ambient() + Kd * diffuse(Nf))
               + specularcolor * (Ks * specular(Nf, V, roughness) + Crefl));
}
