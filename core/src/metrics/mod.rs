//! The figures of ARCHITECTURE §9, with the same definitions as `shared/tools/evaluate.py`.
