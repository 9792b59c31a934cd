// expect: W0012
// Pixie's globals: I and Ns read in a light shader, N written there; each is accepted
// with a warning naming the renderer and saying what rtsl gives.
light pixielight(float intensity = 1;)
{
    N = normal(0, 0, 1);
    illuminate(point(0, 0, 0)) {
        Cl = intensity * max(0, Ns . normalize(-I));
    }
}
