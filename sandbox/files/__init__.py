"""What a simulation reads and writes besides pictures: state files (persist.py: exactly the State's declared
entries), extended-XYZ frames (extxyz.py) and the table of measurements (table.py)."""
