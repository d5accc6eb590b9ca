"""The physics of the model: kinematics of the pouch, resistivity laws, the element equations,
the nodal right-hand side, the model object and statics."""
