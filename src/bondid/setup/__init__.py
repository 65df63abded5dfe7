"""What a command declares about the model besides its files, shared by fit, sensitivity and
diagnosis: the operating points of files that state none (:mod:`.operating_points`) and the
damping model (:mod:`.damping`)."""
