/*
 * glossy.sl -- a glossy (blurred) reflector; this library's own, after the
 * gather() idiom of PRMan's ray-tracing application note and Apodaca &
 * Gritz, "Advanced RenderMan" (ch. 11, blurry reflections).
 *
 * `samples` rays are gathered in a cone of half-angle `blur` (radians)
 * about the mirror direction; the mean of what they see (the hit
 * surfaces' Ci, the environment map where they miss) is the reflection.
 * Plastic-like diffuse and highlight terms are added from the lights.
 * Where the application lowers the ray parameter "relevance" below 1
 * (docs/ray_parameters.md), the cone takes ceil(samples * relevance) rays
 * (at least one), and none once raydepth() reaches 4 * relevance.
 *
 * Parameters:
 *   Ka            -- scale applied to the ambient light (0).
 *   Kd            -- scale applied to the diffuse reflection (.3).
 *   Ks            -- scale applied to the specular highlight (.5).
 *   Kr            -- scale applied to the blurred reflection (.6).
 *   roughness     -- size of the specular highlight (.1).
 *   blur          -- half-angle of the reflection cone, in radians (.1).
 *   samples       -- rays per shading point (16).
 *   envname       -- environment map seen by rays that miss ("": black).
 *   specularcolor -- colour of the highlight and the reflection (1, white).
 */
surface glossy(float Ka = 0; float Kd = .3; float Ks = .5; float Kr = .6;
               float roughness = .1; float blur = .1; float samples = 16;
               string envname = ""; color specularcolor = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    vector R = normalize(reflect(I, Nf));
    uniform float relevance = 1;
    color hitc = 0, sum = 0;
    float n = 0;

    rayinfo("relevance", relevance);
    if (Kr > 0 && (relevance >= 1 || raydepth() < 4 * relevance)) {
        gather("illuminance", P, R, blur, max(1, ceil(samples * relevance)),
               "surface:Ci", hitc) {
            sum += hitc;
            n += 1;
        } else {
            if (envname != "")
                sum += color environment(envname, vtransform("world", R));
            n += 1;
        }
    }

    Oi = Os;
    Ci = Os * (Cs * (Ka * ambient() + Kd * diffuse(Nf))
               + specularcolor * (Ks * specular(Nf, V, roughness)
                                  + Kr * sum / max(n, 1)));
}
