/* contextual_names.sl: RenderMan shaders may use the shader-type words (`surface`, `light`,
 * `displacement`, `volume`, `imager`, and rtsl's `camera`, `pixel` and `lightfield`) as ordinary
 * names; they are shader types only where a shader is defined. Also exercises a function and a
 * parameter named after them, a space named "camera", and message passing beside a variable of the
 * same name. */

float pixel(float x) { return x * 2; }

surface contextual_names(float camera = 1; float Kd = .8; float volume = 1;)
{
    point lightfield = transform("camera", P);
    float pixelsize = pixel(camera);
    normal Nf = faceforward(normalize(N), I);
    color light = color (1, .3, .2), dark = color (.5, .1, .1);
    float surface = 1;
    surface("Kd", surface);
    Oi = Os;
    Ci = Os * Cs * Kd * diffuse(Nf) * pixelsize * (1 + .1 * xcomp(lightfield))
         * mix(dark, light, .5 * volume) * surface;
}
