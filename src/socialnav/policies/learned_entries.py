"""Registry entries of the learned policies; torch is imported only when one is built."""
