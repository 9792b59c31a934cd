// expect: E0111
// illuminance loops are only allowed in surface and volume shaders (and
// their functions), not in light shaders.
light illuminance_in_light(float intensity = 1;)
{
    color total = 0;
    illuminance(Ps) {
        total += Cl;
    }
    Cl = intensity * total;
}
