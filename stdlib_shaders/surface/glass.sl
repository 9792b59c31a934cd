/*
 * glass.sl -- a ray-traced dielectric (glass, water); this library's own,
 * after the BMRT "glass" shader and Apodaca & Gritz, "Advanced RenderMan"
 * (ch. 11, ray-traced reflection and refraction).
 *
 * The Fresnel equations (fresnel()) split the light between a mirror
 * reflection and a refraction, both traced with trace().  The sign of I.N
 * tells a ray entering the glass (I.N < 0: the relative index is 1/eta)
 * from one leaving it (I.N > 0: eta).  Where refract() finds total
 * internal reflection (it returns a zero vector) all the light is
 * reflected.  Light that travelled inside the glass to reach this point
 * (a leaving ray) is attenuated by Beer's law, exp(-absorption * d), with
 * d = length(I), the length of the ray segment (RISpec: I runs from the
 * ray origin to P).  transmitcolor tints each refraction as a thin filter.
 * Highlights from the light sources are added on the outside.  The glass
 * is opaque to the renderer (Oi = 1): everything behind it arrives through
 * the refracted ray.  The renderer bounds the recursion: beyond its ray
 * depth trace() is black.  Where the application lowers the ray parameter
 * "relevance" below 1 (docs/ray_parameters.md), rays are traced only while
 * raydepth() is below 4 * relevance (the highlights stay).
 *
 * Parameters:
 *   Ks            -- scale applied to the specular highlight (.5).
 *   Kr            -- scale applied to the Fresnel reflection (1).
 *   Kt            -- scale applied to the Fresnel transmission (1).
 *   roughness     -- size of the specular highlight (.05).
 *   eta           -- index of refraction of the glass relative to the
 *                    outside (1.5).
 *   specularcolor -- colour of the highlight and the reflection (1, white).
 *   transmitcolor -- colour filter applied to the refracted light (1, white).
 *   absorption    -- absorption per unit of distance travelled inside, per
 *                    colour channel; 0 is perfectly clear (0).
 */
surface glass(float Ks = .5; float Kr = 1; float Kt = 1;
              float roughness = .05; float eta = 1.5;
              color specularcolor = 1; color transmitcolor = 1;
              color absorption = 0;)
{
    normal Nn = normalize(N);
    vector In = normalize(I);
    normal Nf = faceforward(Nn, In, Nn);
    vector V = -In;
    float entering = 1, ior, kr, kt;
    vector T;
    color Crefl = 0, Crefr = 0, Cspec = 0;
    float relevance = 1, traced;

    if (In . Nn > 0)
        entering = 0;
    ior = entering > 0 ? 1 / eta : eta;

    fresnel(In, Nf, ior, kr, kt);
    T = refract(In, Nf, ior);
    if (T . T == 0) {
        /* Total internal reflection. */
        kr = 1;
        kt = 0;
    }

    rayinfo("relevance", relevance);
    traced = relevance >= 1 || raydepth() < 4 * relevance;
    if (traced && Kr * kr > 0)
        Crefl = Kr * kr * color trace(P, reflect(In, Nf));
    if (traced && Kt * kt > 0)
        Crefr = Kt * kt * transmitcolor * color trace(P, T);
    if (entering > 0)
        Cspec = Ks * specular(Nf, V, roughness);

    Oi = 1;
    Ci = specularcolor * (Crefl + Cspec) + Crefr;
    if (entering == 0)
        Ci *= exp(-absorption * length(I));
}
