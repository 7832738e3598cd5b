"""The Active Sketch page (/sketch) on the umbra process's web server."""
