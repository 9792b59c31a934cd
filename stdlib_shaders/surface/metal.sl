/*
 * metal.sl -- RenderMan Interface Specification 3.2, Appendix A (standard
 * surface shaders): "metal".
 *
 * A metallic surface: ambient plus specular reflection only, with the
 * highlight tinted by the surface colour Cs (metals colour their
 * reflections).  There is no diffuse term.
 *
 * Parameters:
 *   Ka        -- scale applied to the ambient light (1).
 *   Ks        -- scale applied to the specular reflection (1).
 *   roughness -- size of the specular highlight; smaller is sharper (.1).
 */
surface metal(float Ka = 1; float Ks = 1; float roughness = .1;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);

    Oi = Os;
    Ci = Os * Cs * (Ka * ambient() + Ks * specular(Nf, V, roughness));
}
