"""Acquisition: rig descriptions and transports (Modbus via pymodbus, serial via pyserial), the recorder that never
loses data, test plans, and a simulated rig that serves a simulated motor over a real transport."""
