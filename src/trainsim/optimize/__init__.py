"""Energy-efficient driving to a timetable."""
