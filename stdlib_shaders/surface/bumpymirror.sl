/*
 * bumpymirror.sl -- a ray-traced mirror with procedural bumps; this
 * library's own, after the bump-mapping idiom of the RISpec (section 15,
 * calculatenormal) and Apodaca & Gritz, "Advanced RenderMan" (ch. 8).
 *
 * The surface point is moved along the normal by fractal noise evaluated
 * in "shader" space (two octaves), the normal of the moved surface is
 * recomputed with calculatenormal() (bump mapping: P itself is not
 * changed), and the scene is reflected with trace() along the mirror
 * direction of that normal, plus "plastic"-like highlights.  The bump
 * height is given in shader-space units.  Where the application lowers the
 * ray parameter "relevance" below 1 (docs/ray_parameters.md), reflections
 * are traced only while raydepth() is below 4 * relevance.
 *
 * calculatenormal() differentiates Pb with respect to the screen: the
 * renderer's ray differentials, carried through noise() by a central
 * difference over the pixel's footprint (docs/packet-abi.md).
 *
 * Parameters:
 *   Ks            -- scale applied to the specular highlight (1).
 *   Kr            -- scale applied to the traced reflection (1).
 *   roughness     -- size of the specular highlight (.05).
 *   specularcolor -- colour of the highlight and the reflection (1, white).
 *   bumpheight    -- amplitude of the bumps in shader-space units (.02).
 *   bumpfreq      -- frequency of the bumps in shader space (8).
 */
surface bumpymirror(float Ks = 1; float Kr = 1; float roughness = .05;
                    color specularcolor = 1;
                    float bumpheight = .02; float bumpfreq = 8;)
{
    normal Nn = normalize(N);
    point PP = bumpfreq * transform("shader", P);
    float h, scale;
    point Pb;
    normal Nb, Nf;
    vector V = -normalize(I), R;
    color Crefl = 0;
    float relevance = 1;

    /* Two octaves of signed noise. */
    h = (float noise(PP) - .5) + .5 * (float noise(2 * PP) - .5);

    /* bumpheight is in shader space: convert it to current space. */
    scale = 1 / length(vtransform("shader", vector Nn));
    Pb = P + bumpheight * scale * h * Nn;

    /* calculatenormal's orientation follows the parametrisation: align it
     * with N before facing it towards the viewer. */
    Nb = normalize(calculatenormal(Pb));
    if (Nb . Nn < 0)
        Nb = -Nb;
    Nf = faceforward(Nb, I);
    R = reflect(normalize(I), Nf);
    rayinfo("relevance", relevance);
    if (Kr > 0 && (relevance >= 1 || raydepth() < 4 * relevance))
        Crefl = Kr * color trace(P, R);

    Oi = Os;
    Ci = Os * specularcolor * (Ks * specular(Nf, V, roughness) + Crefl);
}
