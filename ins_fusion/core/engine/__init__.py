"""The engine: InsEngine (inputs, outputs, the loop), the start-up, the compiled intake and runs
of IMU samples, the warm-up of the kernels, the smoother's side of the engine."""
