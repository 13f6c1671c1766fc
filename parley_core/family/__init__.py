"""SystemModel -> Family: augmentation in the canonical form (:mod:`.augment`), a user's own
PRISM model (:mod:`.usermodel`), scenario sets (:mod:`.scenarios`), and a case study prepared
for a run, pruned on the quotient where it asks (:mod:`.prepare`)."""
