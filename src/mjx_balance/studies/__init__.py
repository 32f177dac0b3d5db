"""Floor 9, studies: experiments built from runs, each resumable in its own folder
(docs/studies.md). docs/architecture.md, "The modules", maps its modules.
"""
