//! plant-host: the simulated machine of the paper's Fig. 3, a two-inertia plant with lost
//! motion reflected to the motor side, in per unit; the motor winding, computational delay
//! and sensor quantization around it; and the linear analysis (nalgebra) that explains it.
//! It knows nothing of the controller.
