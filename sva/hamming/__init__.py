"""The SVA's matching cost: the Hamming distance of a left descriptor to the D right
descriptors of its window (the hybrid: two parts weighted, with the noise unit's automatic
weights). Its reference and kernels (cost, noise), its timing rule (timing: the plan's
``hamming`` stage and the descriptor row banks) and its RTL (sva_hamming.sv)."""
