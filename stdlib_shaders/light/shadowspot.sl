/*
 * shadowspot.sl -- the spotlight of RISpec 3.2 Appendix A with a depth
 * shadow map, as PRMan's and Aqsis's libraries ship it: "shadowspot".
 *
 * The light of spotlight.sl, times the fraction of the shadow map's
 * filter kernel that is lit: 1 - shadow(shadowname, Ps).  The map is a
 * depth render from the light (RIB Display "zfile" or "shadow", then
 * MakeShadow), whose own camera need not match from/to.  With no map
 * named it is spotlight.sl.  rtsl also traces shadow rays to every light
 * unless Attribute "light" "shadows" "off" says not to; with the map,
 * that attribute leaves the map's shadows alone.
 *
 * Parameters: those of spotlight.sl, and
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
light shadowspot(float intensity = 1; color lightcolor = 1;
                 point from = point "shader" (0, 0, 0);
                 point to = point "shader" (0, 0, 1);
                 float coneangle = radians(30);
                 float conedeltaangle = radians(5);
                 float beamdistribution = 2;
                 string shadowname = "";
                 float samples = 16;
                 float width = 1;
                 float blur = 0;
                 float bias = 0.01;
                 output float __nondiffuse = 0;
                 output float __nonspecular = 0;)
{
    uniform vector A = (to - from) / length(to - from);
    uniform float cosoutside = cos(coneangle);
    uniform float cosinside = cos(coneangle - conedeltaangle);
    uniform float relevance = 1;
    float atten, cosangle;

    rayinfo("relevance", relevance);
    illuminate(from, A, coneangle) {
        cosangle = (L . A) / length(L);
        atten = pow(cosangle, beamdistribution) / (L . L);
        atten *= smoothstep(cosoutside, cosinside, cosangle);
        Cl = atten * intensity * lightcolor;
        if (shadowname != "")
            Cl *= 1 - shadow(shadowname, Ps, "samples", max(1, ceil(samples * relevance)), "width", width,
                             "blur", blur, "bias", bias);
    }
}
