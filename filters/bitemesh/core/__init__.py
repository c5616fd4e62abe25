"""The numpy/scipy core of bitemesh: no VTK import anywhere below here."""
