"""The vacancy-chain model: the simulator measured under static allocations, the model's
predictions from those measurements, and the search over the docking world it rests on."""
