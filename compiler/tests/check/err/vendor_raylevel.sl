// expect: W0012
// BMRT's raylevel() is rtsl's raydepth(): the call compiles, with a warning naming
// the renderer that defined it.
surface vendor_raylevel()
{
    Ci = raylevel() > 0 ? color(1, 0, 0) : Cs;
    Oi = Os;
}
