"""Sony FCB block camera over VISCA: protocol framing, serial client, simulated camera on a pty."""
