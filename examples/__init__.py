"""Programs that show umbra beside other systems; each folder says how to run it."""
