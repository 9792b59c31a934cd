/*
 * shadowdistant.sl -- the distantlight of RISpec 3.2 Appendix A with a
 * depth shadow map, as PRMan's and Aqsis's libraries ship it:
 * "shadowdistant".
 *
 * Light arriving along from -> to, times 1 - shadow(shadowname, Ps): the
 * map is a depth render from the light (usually Projection
 * "orthographic"; RIB Display "zfile" or "shadow", then MakeShadow).
 * With no map named it is distantlight.sl.
 *
 * Parameters: those of distantlight.sl, and
 *   shadowname -- the shadow map ("": none).
 *   samples    -- percentage-closer samples per lookup (16); where the
 *                 application lowers the ray parameter "relevance" below 1
 *                 (docs/ray_parameters.md), samples * relevance (at least 1).
 *   width      -- widens the filter kernel (1).
 *   blur       -- blurs it by this fraction of the map (0).
 *   bias       -- depth offset against self-shadowing (0.01).
 *   __nondiffuse, __nonspecular -- 1 leaves the light out of diffuse(),
 *                 and of specular() and phong() (RenderMan's convention; 0).
 */
light shadowdistant(float intensity = 1; color lightcolor = 1;
                    point from = point "shader" (0, 0, 0);
                    point to = point "shader" (0, 0, 1);
                    string shadowname = "";
                    float samples = 16;
                    float width = 1;
                    float blur = 0;
                    float bias = 0.01;
                    output float __nondiffuse = 0;
                    output float __nonspecular = 0;)
{
    uniform float relevance = 1;

    rayinfo("relevance", relevance);
    solar(to - from, 0) {
        Cl = intensity * lightcolor;
        if (shadowname != "")
            Cl *= 1 - shadow(shadowname, Ps, "samples", max(1, ceil(samples * relevance)), "width", width,
                             "blur", blur, "bias", bias);
    }
}
