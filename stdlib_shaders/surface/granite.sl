/*
 * granite.sl -- after the "granite" shader of Upstill's "The RenderMan
 * Companion" (ch. 16): a speckled stone from multi-octave noise.
 *
 * Six octaves of |.5 - noise| at doubling frequencies, each weighted by its
 * inverse frequency, give a speckle value that scales the surface colour.
 * The Companion's version looked the noise up at I; this one uses
 * "shader"-space P so the pattern sticks to the object.  Lit like "matte"
 * plus a small highlight.
 *
 * Parameters:
 *   Ka        -- scale applied to the ambient light (.2).
 *   Kd        -- scale applied to the diffuse reflection (.8).
 *   Ks        -- scale applied to the specular highlight (.2).
 *   roughness -- size of the specular highlight (.2).
 *   frequency -- base frequency of the speckle in shader space (4).
 *   contrast  -- scale of the speckle value; larger is brighter and
 *                more contrasted (2.5).
 */
surface granite(float Ka = .2; float Kd = .8; float Ks = .2;
                float roughness = .2; float frequency = 4;
                float contrast = 2.5;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    point PP = frequency * transform("shader", P);
    float i, freq = 1, sum = 0;

    for (i = 0; i < 6; i += 1) {
        sum += abs(.5 - float noise(PP * freq)) / freq;
        freq *= 2;
    }

    Oi = Os;
    Ci = Os * (Cs * contrast * sum * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * specular(Nf, V, roughness));
}
