"""Floor 2, measures: what a closed loop's motion means (outcome rules, summary columns,
energies, units), written once for every path (docs/model.md, "Samples and outcome rules").
docs/architecture.md, "The modules", maps its modules.
"""
