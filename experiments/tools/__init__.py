"""Code the studies share that the runtime package does not use: the Gaussian mixture baseline
of the pose-prior study (:mod:`.gmm`), the prior trained on real motion capture
(:mod:`.real_prior`), the colour-marker detector (:mod:`.marker_detector`), the robust
per-frame triangulation baseline (:mod:`.triangulation`) and the diagnosis scripts' row reports
(:mod:`.jsonl`)."""
