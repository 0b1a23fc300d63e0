"""The analysis' rendering: markdown tables, READMEs and figures written from what ``experiments.analysis`` computes
(nothing here computes a statistic)."""
