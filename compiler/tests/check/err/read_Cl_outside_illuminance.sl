// expect: E0128
// In a surface shader Cl (and L) hold the light visited by an illuminance
// loop; reading Cl in the shader body outside one has no meaning.
surface read_Cl_outside_illuminance()
{
    Ci = Cs * Cl;
    Oi = Os;
}
