/*
 * shinymetal.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard surface shaders): "shinymetal".
 *
 * The "metal" shader with an added mirror reflection looked up in an
 * environment map.  The reflection direction is taken into world space
 * before the lookup, so the map stays fixed as the camera moves.  When no
 * map is named the reflection term is black and the shader behaves like
 * "metal".
 *
 * Parameters:
 *   Ka          -- scale applied to the ambient light (1).
 *   Ks          -- scale applied to the specular highlight (1).
 *   Kr          -- scale applied to the environment reflection (1).
 *   roughness   -- size of the specular highlight (.1).
 *   texturename -- name of the environment map; "" means none ("").
 */
surface shinymetal(float Ka = 1; float Ks = 1; float Kr = 1;
                   float roughness = .1; string texturename = "";)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    vector D = reflect(I, normalize(Nf));
    color env = 0;

    D = vtransform("world", D);
    if (texturename != "")
        env = Kr * color environment(texturename, D);

    Oi = Os;
    Ci = Os * Cs * (Ka * ambient() + Ks * specular(Nf, V, roughness) + env);
}
