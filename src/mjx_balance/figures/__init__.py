"""Floor 8, figures: matplotlib figures drawn from saved tables, one module per family, all in
one figure style (docs/outputs.md, "Figures: formats, paper sizes, colours").
docs/architecture.md, "The modules", maps its modules.

Each function draws on the Axes it is given (or a new figure) and returns the Figure.
"""
