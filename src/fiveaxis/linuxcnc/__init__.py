"""LinuxCNC: its G-code interpreter rs274 (reading programs), G-code writing, compensation files and kinematics parameters."""
