"""``auto``'s default tolerance, below both the registry (:mod:`camsim.methods`) and the plans
(:mod:`camsim.methods.plan`) that use it, so that neither imports the other for it. Light to import: the command
line and the scene-file reader read it at start-up."""

#: Default ``auto`` tolerance: the largest KS distance accepted between a pixel value's exact law (before
#: quantisation) and the law ``auto`` draws it from, per spectrum and channel. With Table I's 4 e⁻ read noise the
#: Gaussian never exceeds it (worst 0.0065, near 32 e⁻, ``pixel`` statistics); without read noise it needs about
#: 800 e⁻. It bounds one pixel's law, not a frame's: n pixels of a patch detect a KS distance ε once √n ε ≳ 1.63.
DEFAULT_TOLERANCE = 0.01
