"""What the tests share: the independent closed forms (:mod:`tests.support.theory`), scene builders and
small helpers (:mod:`tests.support.helpers`), the fuzzer's mutators and runner (:mod:`tests.support.fuzz`),
a CuPy stand-in (:mod:`tests.support.fake_cupy`), an ISP reference and a phone-DNG writer."""
