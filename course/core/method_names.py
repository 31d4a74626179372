"""Our methods: every strategy the minimizer knows (``course.solver.strategies.make_strategy``),
each with one line saying what it is. Cheap to import: the command line's ``--help`` prints the
table, and ``--methods`` is checked against it (through ``course.backends.registry``, which
adds the peers' methods with theirs).
"""

#: every strategy of the minimizer, in table order: name -> what it is
OUR_METHODS: dict[str, str] = {
    "gauss-newton": "Gauss-Newton: H h = -b, every step taken",
    "lm-type1": "Levenberg-Marquardt, Gavin's update type 1: [H + lambda diag(H)] h = -b; lambda / 9 after an "
                "accepted step, x 11 after a rejected one",
    "lm-type2": "Levenberg-Marquardt, Gavin's update type 2: [H + lambda I] h = -b, the step scaled by a line "
                "search's alpha; lambda / (1 + alpha) after an accepted step",
    "lm-type3": "Levenberg-Marquardt, Gavin's update type 3 (Nielsen's): [H + lambda I] h = -b; lambda x "
                "max(1/3, 1 - (2 rho - 1)^3) after an accepted step, x nu (doubled each time) after a rejected one",
    "lm-scaled-nielsen": "Levenberg-Marquardt with scaled (Marquardt's) damping and Nielsen's update: type 1's "
                         "[H + lambda diag(H)] h = -b with type 3's rule for lambda (Ceres' LM); for parameters of "
                         "very different scales, as bundle adjustment's",
    "lm-source": "Levenberg-Marquardt as chapter 1's C++ source runs it: Gavin's type 3 with lambda_0 = 1e-5 max "
                 "diag(H), a step taken when rho > 0, and the decrease factor capped at 2/3",
    "dogleg": "Powell's dogleg: a trust region; the step runs from the Cauchy point towards the Gauss-Newton step",
}
#: the ones a comparison runs when no ``--methods`` is given: the chapters' (Gauss-Newton, Gavin's
#: three updates, dogleg); the others run when named
DEFAULT_METHODS: tuple[str, ...] = ("gauss-newton", "lm-type1", "lm-type2", "lm-type3", "dogleg")
