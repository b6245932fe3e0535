"""camsim's test suite: a package, so that test modules import their helpers (``tests.support.helpers``, the scene
builders, ``patch_pixels`` and ``render``; ``tests.support.theory``, the independent closed forms) like any module.

pytest's default ``prepend`` import mode puts the repository root (the folder above this package) on ``sys.path``
when it collects the tests, so ``tests.*`` and the checkout's ``camsim`` are found without any path edit in code.
"""
