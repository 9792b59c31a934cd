// A light loop with a category and a cone, and a light shader's illuminate with a cone.
surface lights(float Ks = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    color spec = 0;
    illuminance("specular", P, Nf, 1.5707963) {
        spec += Cl * pow(max(0, normalize(L) . Nf), 20);
    }
    Ci = Ks * spec;
    Oi = Os;
}
