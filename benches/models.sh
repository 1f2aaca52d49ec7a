# The shared real models by name, for the bench scripts (sourced, not run): `model_path NAME`
# prints the model file of `venus`, `meshroom` or `plane` under $DATA, and any other argument as
# it is (a path to a model file).
model_path() {
    case $1 in
        venus) echo "$DATA/venus-realitycapture/venus.nodraco.gltf";;
        meshroom) echo "$DATA/meshroom-esp32cam/texturedMesh.obj";;
        plane) echo "$DATA/sketchfab-plane-meal/scene.gltf";;
        *) echo "$1";;
    esac
}
