"""hammerbit.model: the runtime the HammerBitRock FMU carries (parameters, kernels, stepping)."""
