/* contextual_names.sl: RenderMan shaders may use `camera`, `pixel` and `lightfield` as ordinary
 * names; they are rtsl shader types only where a shader is defined. Also exercises a function and a
 * parameter named after them, and a space named "camera". */

float pixel(float x) { return x * 2; }

surface contextual_names(float camera = 1; float Kd = .8;)
{
    point lightfield = transform("camera", P);
    float pixelsize = pixel(camera);
    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * Cs * Kd * diffuse(Nf) * pixelsize * (1 + .1 * xcomp(lightfield));
}
