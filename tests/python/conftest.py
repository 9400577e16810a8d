"""Imported by pytest before any test module: totalgrad first, so that it
chooses the OpenBLAS kernels before numpy (imported by matplotlib and
pandas) loads OpenBLAS (docs/python.md, "Same bits"). A test module that
imported numpy first would run trials on other kernels, and the bit-for-bit
comparisons with the CLI would fail."""
import totalgrad  # noqa: F401

assert not totalgrad.blas_kernels()[1], totalgrad.blas_kernels()
