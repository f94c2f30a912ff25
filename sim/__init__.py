"""Physics: the ReFlex finger and hand model, operator model and servo emulator."""
