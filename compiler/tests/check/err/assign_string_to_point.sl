// expect: E0103
// A string cannot be assigned to a point: no conversion exists between
// them (only float converts implicitly to a triple).
surface assign_string_to_point()
{
    point Pc = "origin";
    Ci = Cs * noise(Pc);
    Oi = Os;
}
